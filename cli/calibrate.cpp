// clearfit calibrate: a camera model from board views (mrcal's optimizer), or
// converted from an OpenCV calibration / an existing .cameramodel.
#include <clearfit/cli/commands.hpp>
#include <clearfit/cli/video_views.hpp>

#include <clearfit/atomic_file.hpp>
#include <clearfit/memory.hpp>
#include <clearfit/output_folder.hpp>
#include <clearfit/camera/projection_uncertainty.hpp>
#include <clearfit/camera/board.hpp>
#include <clearfit/camera/calibrate.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/detect.hpp>
#include <clearfit/error.hpp>

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

namespace clearfit::cli {
namespace {

namespace fs = std::filesystem;

nlohmann::json finite_or_null(double v) {
  return std::isfinite(v) && v >= 0 ? nlohmann::json(v) : nlohmann::json(nullptr);
}

nlohmann::json corner_json(const CornerResidual& c, const CalibrationResult& r) {
  return {{"image", r.views[static_cast<std::size_t>(c.view)].image},
          {"row", c.row},
          {"col", c.col},
          {"error_px", c.error_px},
          {"observed", {c.observed.x(), c.observed.y()}}};
}

nlohmann::json report_json(const CalibrationResult& r, const CalibrationGrid& grid,
                           const nlohmann::json& inputs, const nlohmann::json& refinement) {
  nlohmann::json views = nlohmann::json::array();
  for (const auto& v : r.views) {
    nlohmann::json j{{"image", v.image}, {"used", v.used}};
    if (v.used) {
      const auto rt = v.cam_from_board.to_rt();
      j.update({{"corners", v.corners},
                {"rms_px", v.rms_px},
                {"distance_mm", v.distance_mm},
                {"tilt_deg", v.tilt_deg},
                {"cam_from_board", {{"r", {rt[0], rt[1], rt[2]}}, {"t", {rt[3], rt[4], rt[5]}}}}});
    }
    views.push_back(j);
  }
  nlohmann::json outliers = nlohmann::json::array(), worst = nlohmann::json::array();
  for (const auto& c : r.outlier_corners) outliers.push_back(corner_json(c, r));
  for (const auto& c : r.worst_corners) worst.push_back(corner_json(c, r));
  nlohmann::json unc = nullptr;
  if (!r.uncertainty_px.empty()) {
    nlohmann::json nodes = nlohmann::json::array();
    double max_px = 0;
    for (double u : r.uncertainty_px) {
      nodes.push_back(finite_or_null(u));
      max_px = std::max(max_px, u);
    }
    unc = {{"method",
            "mrcal's: Var(q) = sigma^2 dq/db inv(JtJ) Jobs^t Jobs inv(JtJ) dq/db^t, mean-frames reference; "
            "J by central differences of mrcal_optimizer_callback"},
           {"what", "worst-direction standard deviation, px"},
           {"distance_mm", r.uncertainty_distance_mm},
           {"observed_pixel_sigma_px", r.observed_pixel_sigma_px},
           {"nodes_x", r.uncertainty_nodes_x},
           {"nodes_y", r.uncertainty_nodes_y},
           {"nodes", "a grid spanning the imager edge to edge, row-major: node i of n at pixel i (W - 1) / (n - 1)"},
           {"nodes_px", nodes},
           {"centre_px", finite_or_null(r.uncertainty_center_px)},
           {"max_px", max_px}};
  }
  return {
      {"schema", "clearfit.calibration/1"},
      {"inputs", inputs},
      {"board", {{"grid_width", grid.width}, {"grid_height", grid.height}, {"spacing_mm", grid.spacing_mm}}},
      {"lensmodel", r.model.lensmodel},
      {"lensmodel_chain", r.lensmodel_chain},
      {"imagersize", {r.model.width, r.model.height}},
      {"intrinsics", r.model.intrinsics},
      {"rms_px", r.rms_px},
      {"mrcal_rms_px", r.mrcal_rms_px},
      {"corner_weight_scale", r.corner_weight_scale},
      {"seed", {{"focal_px", r.focal_seed_px}, {"method", r.focal_seed_method}, {"rms_px", r.seed_rms_px}}},
      {"corners_used", r.corners_used},
      {"outliers", {{"count", r.outliers}, {"corners", outliers}}},
      {"worst_corners", worst},
      {"views", views},
      {"calobject_warp_mm", {{"x2", r.calobject_warp_x_mm}, {"y2", r.calobject_warp_y_mm}}},
      {"coverage",
       {{"cells_x", r.coverage_cells_x}, {"cells_y", r.coverage_cells_y}, {"corners", r.coverage}}},
      {"uncertainty", unc},
      {"refinement", refinement},
      {"timings_s", {{"solve", r.solve_seconds}, {"uncertainty", r.uncertainty_seconds}}},
      {"warnings", r.warnings},
      {"notes", r.notes}};
}

void print_summary(const CalibrationResult& r, std::ostream& out) {
  int used = 0;
  for (const auto& v : r.views) used += v.used;
  out << "calibrated " << r.model.lensmodel << " (" << r.lensmodel_chain << ") from " << used << " views, "
      << r.corners_used << " corners, " << r.outliers << " outliers\n";
  out << std::setprecision(4) << "RMS " << r.rms_px << " px (mrcal's figure " << r.mrcal_rms_px << ")";
  if (!r.worst_corners.empty()) {
    const auto& w = r.worst_corners.front();
    out << "; worst corner " << w.error_px << " px (" << r.views[static_cast<std::size_t>(w.view)].image
        << " row " << w.row << " col " << w.col << ")";
  }
  out << "\nfx " << r.model.intrinsics[0] << "  fy " << r.model.intrinsics[1] << "  cx "
      << r.model.intrinsics[2] << "  cy " << r.model.intrinsics[3] << "\n";
  if (!r.uncertainty_px.empty()) {
    const auto worst = std::max_element(r.uncertainty_px.begin(), r.uncertainty_px.end());
    const Vec2 at = uncertainty_sample_pixels(ProjectionUncertainty::Layout::nodes, r.uncertainty_nodes_x, r.uncertainty_nodes_y,
                                              r.model.width, r.model.height)[static_cast<std::size_t>(worst - r.uncertainty_px.begin())];
    out << "projection uncertainty at " << std::setprecision(4) << r.uncertainty_distance_mm << " mm: centre "
        << r.uncertainty_center_px << " px, worst over the image " << *worst << " px at pixel (" << at.x() << ", " << at.y()
        << ") (noise " << r.observed_pixel_sigma_px << " px)\n";
  }
  out << "solve " << std::setprecision(3) << r.solve_seconds << " s"
      << (r.uncertainty_px.empty()
              ? ""
              : ", uncertainty " + std::to_string(r.uncertainty_seconds).substr(0, 5) + " s")
      << "\n";
  for (const auto& w : r.warnings) out << "warning: " << w << "\n";
}

/// The command line of `clearfit calibrate`.
struct CalibrateArgs {
  std::string board, corners, out, report, from_opencv, from_cameramodel, seed, lensmodel = "LENSMODEL_OPENCV8";
  std::string corners_out;
  std::vector<int> grid, imagersize;
  std::vector<std::string> images;
  double spacing_mm = 0, focal = 0, uncertainty_distance_mm = 0;
  bool no_uncertainty = false, no_outlier_rejection = false, no_warp = false, no_refine = false;
  bool mrcal_regularization = false;
  ViewSelectionOptions video;
};

/// --from-opencv / --from-cameramodel: an existing calibration checked and rewritten.
int convert_model(const CalibrateArgs& a) {
  if (!a.from_opencv.empty() && !a.from_cameramodel.empty())
    throw InputError("", "--from-opencv", "cannot be combined with --from-cameramodel");
  if (!a.images.empty() || !a.corners.empty())
    throw InputError("", a.from_opencv.empty() ? "--from-cameramodel" : "--from-opencv",
                     "converts a model; it cannot be combined with images or --corners");
  const CameraModel m = a.from_opencv.empty() ? read_cameramodel(a.from_cameramodel)
                                               : camera_from_opencv_yaml(a.from_opencv);
  write_cameramodel(m, a.out);
  if (!a.report.empty())
    write_file_atomically(
        a.report,
        nlohmann::json{
            {"schema", "clearfit.calibration/1"},
            {"inputs",
             {{"converted_from", a.from_opencv.empty() ? a.from_cameramodel : a.from_opencv}}},
            {"lensmodel", m.lensmodel},
            {"imagersize", {m.width, m.height}},
            {"intrinsics", m.intrinsics}}
                .dump(2) +
            "\n");
  std::cout << "converted to " << m.lensmodel << " (" << m.width << " x " << m.height << "); wrote "
            << a.out << "\n";
  return 0;
}

/// The camera model, the report and the corners written; the files already written are removed on failure.
std::vector<std::string> write_calibration(const CalibrateArgs& a, const CalibrationResult& result, const nlohmann::json& report,
                                           const BoardViews& views, const std::optional<Board>& board) {
  std::vector<std::string> written;
  try {
    // The projection uncertainty travels with the model (projection_uncertainty.hpp) when every node has one.
    const bool uncertainty = !result.uncertainty_px.empty() &&
                             std::all_of(result.uncertainty_px.begin(), result.uncertainty_px.end(), [](double v) { return v >= 0; });
    if (uncertainty)
      write_cameramodel(result.model,
                        ProjectionUncertainty{result.uncertainty_nodes_x, result.uncertainty_nodes_y, result.uncertainty_distance_mm,
                                              result.uncertainty_px, ProjectionUncertainty::Layout::nodes},
                        a.out);
    else
      write_cameramodel(result.model, a.out);
    written.push_back(a.out);
    if (!a.report.empty()) {
      write_file_atomically(a.report, report.dump(2) + "\n");
      written.push_back(a.report);
    }
    if (!a.corners_out.empty()) {
      if (board)
        write_corners_vnl(views.views, *board, a.corners_out);
      else
        write_corners_levels_vnl(views.views, a.corners_out);
      written.push_back(a.corners_out);
    }
  } catch (...) {
    std::error_code ignored;
    for (const auto& w : written) fs::remove(w, ignored);
    throw;
  }
  return written;
}

}  // namespace

Run add_calibrate(CLI::App& app) {
  auto o = std::make_shared<CalibrateArgs>();
  CLI::App* sub = app.add_subcommand(
      "calibrate",
      "Camera calibration from board views with mrcal's optimizer (or conversion of an existing model)");
  sub->add_option("images", o->images,
                  "Board images, folders of images or videos (detected with --board; from a video the sharp, distinct frames)");
  sub->add_option("--board", o->board, "Board file (clearfit.board/1) describing the printed board");
  sub->add_option("--grid", o->grid, "Corner grid W H (instead of --board, with --corners)")->expected(2);
  sub->add_option("--spacing-mm", o->spacing_mm, "Corner spacing in mm (with --grid)");
  sub->add_option("--corners", o->corners, "mrcal corners file (corners.vnl) instead of images");
  sub->add_option("--imagersize", o->imagersize, "Image size W H (needed with --corners)")->expected(2);
  sub->add_option("--lensmodel", o->lensmodel,
                  "mrcal lens model, e.g. LENSMODEL_OPENCV8, "
                  "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=12_fov_x_deg=120")
      ->capture_default_str();
  sub->add_option("--focal", o->focal, "Focal length seed in pixels (default: from the board homographies)");
  sub->add_option("--seed", o->seed, "Seed the intrinsics from this .cameramodel (same lens model and size)");
  sub->add_option(
      "--uncertainty-distance-mm", o->uncertainty_distance_mm,
      "Distance of the points the projection uncertainty is evaluated at (default: median board distance)");
  sub->add_flag("--no-uncertainty", o->no_uncertainty, "Skip the projection uncertainty");
  sub->add_flag("--no-outlier-rejection", o->no_outlier_rejection, "Keep every corner");
  sub->add_flag("--no-warp", o->no_warp, "Do not solve for the board's warp (a perfectly flat board)");
  sub->add_flag("--mrcal-regularization", o->mrcal_regularization,
                "Keep mrcal's regularisation as mrcal-calibrate-cameras sizes it (for 1 px corners) even where "
                "scaling it to the corners' noise fits them better (for comparisons)");
  sub->add_flag("--no-refine", o->no_refine,
                "Images: skip the lens-aware corner refinement and second solve");
  sub->add_option("--corners-out", o->corners_out, "Write the corners used (mrcal corners.vnl)");
  sub->add_option("--from-opencv", o->from_opencv,
                  "Convert an OpenCV calibration (YAML/XML) instead of calibrating");
  sub->add_option("--from-cameramodel", o->from_cameramodel, "Check and rewrite an existing .cameramodel");
  sub->add_option("--out", o->out, "Output camera model (.cameramodel)");
  sub->add_option("--report", o->report, "Calibration report (JSON, schema clearfit.calibration/1)");
  add_video_options(*sub, o->video);

  return [o]() -> int {
    if (o->out.empty()) throw InputError("", "--out", "is required", "e.g. --out camera.cameramodel");
    check_output_folder(o->out);
    check_output_folder(o->report);
    check_output_folder(o->corners_out);

    if (!o->from_opencv.empty() || !o->from_cameramodel.empty()) return convert_model(*o);

    // --- the board ---------------------------------------------------------
    std::optional<Board> board;
    CalibrationGrid grid;
    if (!o->board.empty()) {
      if (!o->grid.empty() || o->spacing_mm != 0)
        throw InputError("", "--board", "give either --board or --grid with --spacing-mm, not both");
      board = read_board(o->board);
      grid = CalibrationGrid::of(*board);
    } else {
      if (o->grid.size() != 2)
        throw InputError("", "--board", "is required (or --grid W H with --spacing-mm S)",
                         "the board file written by `clearfit board`");
      grid = {o->grid[0], o->grid[1], o->spacing_mm};
    }
    grid.validate();

    check_calibration_lensmodel(o->lensmodel);
    CalibrationOptions opt;
    opt.lensmodel = o->lensmodel;
    opt.focal_px = o->focal;
    opt.compute_uncertainty = !o->no_uncertainty;
    opt.outlier_rejection = !o->no_outlier_rejection;
    opt.solve_calobject_warp = !o->no_warp;
    opt.scale_regularization_to_noise = !o->mrcal_regularization;
    opt.uncertainty_distance_mm = o->uncertainty_distance_mm;
    opt.progress = [](const std::string& s) { std::cerr << s << "\n"; };
    if (!(std::isfinite(o->focal) && o->focal >= 0))
      throw InputError("", "--focal", "must be a positive focal length in pixels");
    if (!(std::isfinite(o->uncertainty_distance_mm) && o->uncertainty_distance_mm >= 0))
      throw InputError("", "--uncertainty-distance-mm", "must be a positive distance in mm");
    if (!o->seed.empty()) opt.seed = read_cameramodel(o->seed);

    // --- the corners -------------------------------------------------------
    BoardViews views;
    nlohmann::json inputs;
    if (!o->corners.empty()) {
      if (!o->images.empty()) throw InputError("", "--corners", "give either --corners or images, not both");
      if (o->imagersize.size() != 2)
        throw InputError("", "--imagersize",
                         "is required with --corners (corners files do not hold the image size)",
                         "e.g. --imagersize 1920 1080");
      views.views = read_corners_vnl(o->corners, grid, o->imagersize[0], o->imagersize[1]);
      inputs = {{"corners", o->corners}};
    } else {
      if (o->images.empty())
        throw InputError("", "images", "no board images or --corners were given",
                         "clearfit calibrate --board board.yaml images/ --out camera.cameramodel");
      if (!board) throw InputError("", "--board", "is required to detect the board in images");
      views = detect_board_views(o->images, *board, {}, o->video, [](int done, int total) {
        if (done == total || done % 10 == 0) std::cerr << "  " << done << " / " << total << "\n";
      });
      inputs = {{"images", o->images}};
      if (!views.videos.empty()) inputs["videos"] = views.videos;
    }
    keep_freed_memory();  // libmrcal's solver allocates afresh every iteration: reuse the pages
    const auto t0 = std::chrono::steady_clock::now();
    const bool refine = o->corners.empty() && !o->no_refine;
    CalibrationOptions first = opt;
    first.compute_uncertainty = opt.compute_uncertainty && !refine;  // only for the final solve
    CalibrationResult result = calibrate_camera(views.views, grid, first);
    nlohmann::json refinement = nullptr;
    if (refine) {
      // Lens-aware corner refinement: edges fitted in undistorted
      // coordinates with the first solution, then solved again from it.
      std::cerr << "refining the corners with the lens model\n";
      const double first_rms = result.rms_px;
      for (std::size_t k = 0; k < views.views.size(); ++k)
        if (views.views[k].detected()) views.views[k] = refine_corners(views.image(k), views.views[k], *board, &result.model);
      opt.seed = result.model;
      result = calibrate_camera(views.views, grid, opt);
      refinement = {{"first_rms_px", first_rms}, {"refined_rms_px", result.rms_px}};
    }
    const double total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    // --- outputs -------------------------------------------------------
    nlohmann::json report = report_json(result, grid, inputs, refinement);
    report["timings_s"]["total"] = total_s;
    const std::vector<std::string> written = write_calibration(*o, result, report, views, board);
    for (const auto& n : result.notes) std::cerr << "note: " << n << "\n";
    for (const auto& line : views.summaries) std::cout << line << "\n";
    print_summary(result, std::cout);
    std::cout << "wrote";
    for (const auto& w : written) std::cout << " " << w;
    std::cout << "\n";
    return 0;
  };
}

static const Registration registered{"calibrate", 32, add_calibrate};

}  // namespace clearfit::cli
