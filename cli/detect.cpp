// clearfit detect: AprilTag board corners of many images -> mrcal's corners.vnl.
#include <clearfit/cli/commands.hpp>
#include <clearfit/cli/video_views.hpp>

#include <clearfit/camera/board.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/detect.hpp>
#include <clearfit/error.hpp>
#include <iostream>
#include <opencv2/imgcodecs.hpp>

namespace clearfit::cli {

Run add_detect(CLI::App& app) {
  struct Opts {
    std::string board, out, camera;
    std::vector<std::string> inputs;
    DetectOptions detect;
    ViewSelectionOptions video;
    bool quiet = false;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand(
      "detect", "Detect an AprilTag board in images; write mrcal's corners.vnl (with weights)");
  sub->add_option("inputs", o->inputs, "Image files, folders of images and/or videos (from a video: its sharp, distinct frames)")->required();
  sub->add_option("--board", o->board, "Board file (clearfit.board/1, from `clearfit board --board-file`)")
      ->required();
  sub->add_option(
         "--out", o->out,
         "corners.vnl to write (4th column is a weight: mrcal-calibrate-cameras --corners-cache-has-weights)")
      ->required();
  sub->add_option(
      "--camera", o->camera,
      "A first calibration of this camera (.cameramodel): refine corners through its lens (removes the "
      "outward bias distortion gives AprilTag corners)");
  sub->add_option("--decimate", o->detect.quad_decimate,
                  "AprilTag quad_decimate (speed; corners are refined at full resolution)")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 8.0));
  sub->add_option("--quad-sigma", o->detect.quad_sigma, "AprilTag quad_sigma, px (0.8 helps noisy images)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
  sub->add_option("--min-margin", o->detect.min_decision_margin,
                  "Reject tags decoded with a smaller decision margin (ambiguous)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  add_video_options(*sub, o->video);
  sub->add_flag("--quiet", o->quiet, "No per-image lines");
  return [o]() {
    const Board board = read_board(o->board);
    std::optional<CameraModel> lens;
    if (!o->camera.empty()) lens = read_cameramodel(o->camera);
    std::cerr << "board: " << describe(board) << "\n";
    auto progress = [](int done, int total) {
      std::cerr << "\rdetecting: " << done << "/" << total << " images" << (done == total ? "\n" : "")
                << std::flush;
    };
    BoardViews found = detect_board_views(o->inputs, board, o->detect, o->video, progress);
    std::vector<BoardObservation>& obs = found.views;
    if (lens) {
      for (std::size_t i = 0; i < obs.size(); ++i) {
        if (!obs[i].detected()) continue;
        if (obs[i].width != lens->width || obs[i].height != lens->height)
          throw InputError(obs[i].image, "",
                           "image is " + std::to_string(obs[i].width) + "x" + std::to_string(obs[i].height) +
                               ", the camera model " + o->camera + " is " + std::to_string(lens->width) +
                               "x" + std::to_string(lens->height),
                           "use the model of the camera that took it");
        obs[i] = refine_corners(found.image(i), obs[i], board, &*lens);
        progress(static_cast<int>(i + 1), static_cast<int>(obs.size()));
      }
    }
    int with = 0, corners = 0;
    for (const auto& ob : obs) {
      with += ob.detected();
      corners += ob.num_valid();
      if (!o->quiet) {
        std::cout << ob.image << ": " << ob.tags_used << " tags, " << ob.num_valid() << "/"
                  << board.num_points() << " corners\n";
        for (const auto& n : ob.notes) std::cout << "  " << n << "\n";
      }
    }
    if (with == 0)
      throw InputError(
          o->board, "", "the board was found in none of the " + std::to_string(obs.size()) + " images",
          "check the board file against the printed board (family, first id) and the notes above");
    write_corners_vnl(obs, board, o->out);
    for (const auto& line : found.summaries) std::cout << line << "\n";
    std::cout << "board found in " << with << " of " << obs.size() << " images, " << corners << " corners -> "
              << o->out << "\nmrcal: mrcal-calibrate-cameras --corners-cache " << o->out
              << " --corners-cache-has-weights"
              << " --object-spacing " << board.spacing_mm << " --object-width-n " << board.grid_width
              << " --object-height-n " << board.grid_height << " ...\n";
    return 0;
  };
}

static const Registration registered{"detect", 31, add_detect};

}  // namespace clearfit::cli
