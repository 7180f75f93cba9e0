// clearfit pose: the part's pose (cam_from_part) from AprilTags on the part's fixture.
#include <clearfit/cli/commands.hpp>
#include <clearfit/cli/options.hpp>
#include <clearfit/cli/video_views.hpp>

#include <clearfit/atomic_file.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/detect.hpp>
#include <clearfit/camera/pose_file.hpp>
#include <clearfit/camera/tag_pose.hpp>
#include <clearfit/error.hpp>
#include <clearfit/geometry/ray_index.hpp>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

namespace clearfit::cli {

Run add_pose(CLI::App& app) {
  struct Opts {
    std::string camera, layout, out, write_camera, report, mesh;
    std::vector<std::string> images;
    Scene scene;  // --units, as the scene file names it
    SceneFields::Options options;
    DetectOptions detect;
    ViewSelectionOptions video;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand(
      "pose", "The part's pose in the camera frame (cam_from_part) from AprilTags on its fixture");
  sub->add_option("images", o->images, "Images or videos from one camera pose (files and/or folders; from a video: its sharpest frames)")->required();
  sub->add_option("--camera", o->camera, "Calibrated camera (.cameramodel)")->required();
  sub->add_option("--layout", o->layout,
                  "Tag layout (clearfit.tag-layout/1): tag ids and corner positions in the part frame, mm")
      ->required();
  sub->add_option("--out", o->out, "Pose file to write (clearfit.pose/1, read by `clearfit map --pose`)");
  sub->add_option("--write-camera", o->write_camera,
                  "Also write the camera model with cam_from_part as its extrinsics");
  sub->add_option("--report", o->report, "JSON report: pose, RMS, uncertainty, tags used, notes");
  sub->add_option("--mesh", o->mesh,
                  "The part's mesh: refuse tags the camera sees through the part (refraction)");
  o->options = add_scene_options(*sub, o->scene, {"units"});
  sub->add_option("--decimate", o->detect.quad_decimate, "AprilTag quad_decimate")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 8.0));
  add_video_options(*sub, o->video, false);
  return [o]() {
    check_scene(o->scene, o->options);
    const CameraModel camera = read_cameramodel(o->camera);
    const TagLayout layout = read_tag_layout(o->layout);
    const ViewInputs inputs = split_view_inputs(o->images);
    std::vector<std::pair<std::string, cv::Mat>> images;
    for (const auto& path : inputs.images) {
      const cv::Mat img = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
      if (img.empty()) throw InputError(path.string(), "", "cannot be read as an image");
      images.emplace_back(path.string(), img);
    }
    nlohmann::json videos = nlohmann::json::array();
    for (const auto& video : inputs.videos) {
      VideoViews v = read_tag_video(video, layout, o->detect, o->video);
      std::cerr << v.summary() << "\n";
      std::cout << v.summary() << "\n";
      videos.push_back(v.json());
      for (std::size_t k = 0; k < v.images.size(); ++k) images.emplace_back(v.names[k], v.images[k]);
    }
    std::vector<std::vector<DetectedTag>> detections;
    for (const auto& [path, img] : images) {
      if (img.cols != camera.width || img.rows != camera.height)
        throw InputError(path, "",
                         "image is " + std::to_string(img.cols) + "x" + std::to_string(img.rows) +
                             ", the camera model " + std::to_string(camera.width) + "x" +
                             std::to_string(camera.height),
                         "use the model of the camera that took it");
      std::vector<std::string> notes;
      detections.push_back(detect_tags(img, layout.family, o->detect, &camera, &notes));
      std::cerr << path << ": " << detections.back().size() << " " << layout.family << " tags\n";
      for (const auto& n : notes) std::cerr << "  " << n << "\n";
    }
    const PartPose pose = solve_part_pose(camera, layout, detections);
    if (!o->mesh.empty()) {
      const Mesh mesh = load_part(o->mesh, o->scene.part.units);
      const auto index = make_ray_index(mesh);
      const std::vector<int> through = tags_seen_through_part(*index, pose, layout);
      if (!through.empty()) {
        std::string ids;
        for (int id : through) {
          if (!ids.empty()) ids += ", ";
          ids += std::to_string(id);
        }
        throw InputError(
            o->layout, "tag " + ids,
            "seen through the part: refraction in the part moves its corners and would bias the pose",
            "put pose tags on the fixture beside the part, or flag them `through_part: true` in the layout");
      }
    }
    const auto rt = pose.cam_from_part.to_rt();
    std::printf("cam_from_part: r = [%.9g, %.9g, %.9g] rad, t = [%.6f, %.6f, %.6f] mm\n", rt[0], rt[1], rt[2],
                rt[3], rt[4], rt[5]);
    std::printf("tags %d, corners %d, images %d, reprojection RMS %.4f px (noise %.4f px, %d outliers)\n",
                pose.tags, pose.corners, pose.images, pose.rms_px, pose.noise_px, pose.outliers);
    std::printf("1-sigma: translation %.4f %.4f %.4f mm, rotation %.4f %.4f %.4f deg (camera axes x y z)\n",
                pose.sigma_translation_mm.x(), pose.sigma_translation_mm.y(), pose.sigma_translation_mm.z(),
                pose.sigma_rotation_deg.x(), pose.sigma_rotation_deg.y(), pose.sigma_rotation_deg.z());
    for (const auto& n : pose.notes) std::printf("note: %s\n", n.c_str());
    if (!o->out.empty()) write_pose_json(pose.cam_from_part, o->out, pose.covariance);
    if (!o->write_camera.empty()) {
      CameraModel with = camera;
      with.cam_from_part = pose.cam_from_part;
      write_cameramodel(with, o->write_camera);
    }
    if (!o->report.empty()) {
      nlohmann::json report = nlohmann::json::parse(part_pose_report_json(pose));
      if (!videos.empty()) report["videos"] = videos;
      write_file_atomically(o->report, report.dump(2) + "\n");
    }
    return 0;
  };
}

static const Registration registered{"pose", 33, add_pose};

}  // namespace clearfit::cli
