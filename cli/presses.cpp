// clearfit presses: a calibration session (the recording of the skin pressed by
// a clear flat indenter, and the force gauge's log) → presses.csv for
// `clearfit calibrate-pressure`, with each press's radial signal profile, and a
// session report (JSON + PNG).
#include <clearfit/output_folder.hpp>
#include <clearfit/cli/commands.hpp>

#include <clearfit/atomic_file.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/error.hpp>
#include <clearfit/fit/session_presses.hpp>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <iostream>
#include <numbers>
#include <sstream>

namespace clearfit::cli {
namespace {

std::string join(const std::vector<double>& v, std::size_t count) {
  std::ostringstream s;
  s.precision(7);
  for (std::size_t i = 0; i < count; ++i) s << (i ? ";" : "") << (std::isfinite(v[i]) ? v[i] : 0.0);
  return s.str();
}

std::string presses_csv(const SessionAnalysis& s, double radius_mm, double sphere_radius_mm) {
  std::ostringstream out;
  out.precision(9);
  out << "# clearfit presses: " << s.video.string() << " + " << s.force_log.string() << "; clock offset " << s.clock.offset_s
      << " s, drift " << s.clock.drift * 1e6 << " ppm\n";
  out << "trial,indenter_diameter_mm,force_n,mean_pressure_kpa,signal,force_sd_n,hold_frames,rest_frames,ring_edges_mm,ring_signal"
      << (sphere_radius_mm > 0 ? ",sphere_radius_mm" : "") << "\n";
  for (std::size_t k = 0; k < s.presses.size(); ++k) {
    const SessionPress& p = s.presses[k];
    const double kpa = 1000 * p.force.force_n / (std::numbers::pi * radius_mm * radius_mm);
    out << k + 1 << "," << 2 * radius_mm << "," << p.force.force_n << "," << kpa << "," << p.signal << "," << p.force.force_sd_n << ","
        << p.hold_frames << "," << p.rest_frames << "," << join(s.ring_edges_mm, s.ring_edges_mm.size()) << ","
        << join(p.ring_signal, p.ring_signal.size());
    if (sphere_radius_mm > 0) out << "," << sphere_radius_mm;
    out << "\n";
  }
  return out.str();
}

nlohmann::json report_json(const SessionAnalysis& s, const SessionOptions& o) {
  using nlohmann::json;
  json presses = json::array();
  for (const auto& p : s.presses)
    presses.push_back({{"force_n", p.force.force_n}, {"force_sd_n", p.force.force_sd_n}, {"log_line", p.log_line},
                       {"gauge", {{"start_s", p.force.start_s}, {"end_s", p.force.end_s}}},
                       {"video", {{"hold_s", {p.hold_start_s, p.hold_end_s}}, {"rest_s", {p.rest_start_s, p.rest_end_s}}}},
                       {"hold_frames", p.hold_frames}, {"rest_frames", p.rest_frames}, {"signal", p.signal}});
  return {{"schema", "clearfit.calibration-session/1"},
          {"inputs", {{"video", s.video.string()}, {"force_log", s.force_log.string()}}},
          {"video", {{"frames", s.frames}, {"fps", s.fps}, {"width", s.width}, {"height", s.height}}},
          {"clock", {{"offset_s", s.clock.offset_s}, {"offset_sigma_s", s.clock.offset_sigma_s}, {"drift_ppm", s.clock.drift * 1e6},
                     {"drift_sigma_ppm", s.clock.drift_sigma * 1e6}, {"correlation", s.clock.correlation},
                     {"second_peak_ratio", s.clock.second_peak_ratio}, {"events", s.clock.events}, {"trace_fit", s.clock.trace_fit},
                     {"tau_on_s", s.clock.tau_on_s}, {"tau_off_s", s.clock.tau_off_s},  // NaN is written as null
                     {"note", "gauge time = (1 + drift) * video time + offset"}}},
          {"tare_n", s.tare_n},
          {"indenter", {{"radius_mm", o.indenter_radius_mm}, {"found", s.centre_found}, {"centre_px", {s.centre_px.x(), s.centre_px.y()}},
                        {"centre_mm", {s.centre_mm.x(), s.centre_mm.y()}}, {"mm_per_px", s.mm_per_px},
                        {"slab_mm", o.optics.slab_mm}, {"slab_ior", o.optics.slab_ior}, {"distance_mm", o.optics.distance_mm}}},
          {"ring_edges_mm", s.ring_edges_mm},
          {"presses", presses},
          {"warnings", s.warnings}};
}

/// Force and image signal on the video's clock (press holds green, rests grey), and the blanching map with the indenter found.
cv::Mat report_png(const SessionAnalysis& s, double radius_mm) {
  const int W = 1200, H = 360, left = 60, right = 20, top = 30, bottom = 40;
  cv::Mat plot(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  const double t1 = s.time_s.back();
  auto x = [&](double t) { return static_cast<int>(left + t / t1 * (W - left - right)); };
  for (const auto& p : s.presses) {
    cv::rectangle(plot, cv::Point(x(p.rest_start_s), top), cv::Point(x(p.rest_end_s), H - bottom), cv::Scalar(225, 225, 225), cv::FILLED);
    cv::rectangle(plot, cv::Point(x(p.hold_start_s), top), cv::Point(x(p.hold_end_s), H - bottom), cv::Scalar(200, 240, 200), cv::FILLED);
  }
  auto curve = [&](const std::vector<double>& t, const std::vector<double>& v, cv::Scalar colour) {
    double lo = 1e300, hi = -1e300;
    for (double a : v) if (std::isfinite(a)) lo = std::min(lo, a), hi = std::max(hi, a);
    std::vector<cv::Point> pts;
    for (std::size_t i = 0; i < t.size(); ++i)
      if (t[i] >= 0 && t[i] <= t1 && std::isfinite(v[i]))
        pts.emplace_back(x(t[i]), static_cast<int>(H - bottom - (v[i] - lo) / std::max(hi - lo, 1e-12) * (H - top - bottom)));
    cv::polylines(plot, pts, false, colour, 1, cv::LINE_AA);
  };
  curve(s.force_time_s, s.force_n, cv::Scalar(180, 90, 20));
  curve(s.time_s, s.trace, cv::Scalar(40, 140, 40));
  cv::rectangle(plot, cv::Point(left, top), cv::Point(W - right, H - bottom), cv::Scalar(0, 0, 0), 1);
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  cv::putText(plot, "video time 0 - " + std::to_string(static_cast<int>(t1)) + " s; blue: force (gauge clock aligned), green: indenter signal; "
              "shaded: holds (green), rests (grey)", cv::Point(left, 20), font, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  // The blanching map, scaled to 300 px high, the indenter's rim.
  cv::Mat map8, map;
  double lo = 0, hi = 0;
  cv::minMaxLoc(s.blanching, &lo, &hi);
  s.blanching.convertTo(map8, CV_8U, 255 / std::max(hi - lo, 1e-9), -lo * 255 / std::max(hi - lo, 1e-9));
  cv::applyColorMap(map8, map, cv::COLORMAP_VIRIDIS);
  const double scale = 300.0 / s.height;
  cv::resize(map, map, cv::Size(), scale, scale, cv::INTER_NEAREST);
  const cv::Point c(static_cast<int>((s.centre_px.x() + 0.5) * scale), static_cast<int>((s.centre_px.y() + 0.5) * scale));
  cv::circle(map, c, static_cast<int>(radius_mm / s.mm_per_px * scale), cv::Scalar(255, 0, 255), 1, cv::LINE_AA);
  cv::drawMarker(map, c, cv::Scalar(255, 0, 255), cv::MARKER_CROSS, 12);
  cv::Mat bottom_row(map.rows + 30, W, CV_8UC3, cv::Scalar(255, 255, 255));
  map.copyTo(bottom_row(cv::Rect(left, 25, std::min(map.cols, W - left), map.rows)).colRange(0, std::min(map.cols, W - left)));
  cv::putText(bottom_row, std::string("blanching summed over the presses; magenta: the indenter ") + (s.centre_found ? "found" : "given"),
              cv::Point(left, 18), font, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::Mat img;
  cv::vconcat(plot, bottom_row, img);
  return img;
}

}  // namespace

Run add_presses(CLI::App& app) {
  struct Opts {
    std::string video, force_log, camera, out, report;
    std::vector<double> centre;
    double sphere_radius_mm = 0;
    SessionOptions session;
  };
  auto o = std::make_shared<Opts>();
  SessionOptions& s = o->session;
  CLI::App* sub = app.add_subcommand("presses",
      "Calibration presses from a session: the recording of the skin pressed by a clear flat indenter and the force gauge's log");
  sub->add_option("--video", o->video, "The session's recording (video file or folder of frames)")->required();
  sub->add_option("--force-log", o->force_log, "Force log CSV (time and force columns with units in the header, e.g. time_s,force_n)")->required();
  sub->add_option("--camera", o->camera, "Camera model (.cameramodel) of the recording; its axis along the indenter's")->required();
  sub->add_option("--indenter-radius-mm", s.indenter_radius_mm,
                  "Radius a of the flat cylindrical indenter, mm (a sphere: the radius of its cap, the disc read)")->required();
  sub->add_option("--sphere-radius-mm", o->sphere_radius_mm,
                  "The indenter is a sphere of this radius, mm (written with the presses: calibrate-pressure fits Hertz's pressure)");
  sub->add_option("--distance-mm", s.optics.distance_mm, "Camera centre to skin along the axis, mm")->capture_default_str();
  sub->add_option("--slab-mm", s.optics.slab_mm, "Thickness of the clear indenter the camera looks through, mm (0: directly)")->capture_default_str();
  sub->add_option("--slab-ior", s.optics.slab_ior, "Its refractive index")->capture_default_str();
  sub->add_option("--centre-px", o->centre, "The indenter's centre in the image (x y, px); found when absent")->expected(2);
  sub->add_option("--fps", s.fps, "Frame rate (default: the video's; required for a folder of frames)");
  sub->add_option("--ring-mm", s.ring_mm, "Ring width of the radial profile, mm on the skin")->capture_default_str();
  sub->add_option("--out", o->out, "Output presses CSV (for calibrate-pressure)")->required();
  sub->add_option("--report", o->report, "Folder for the session report (session.json, session.png)");

  return [o]() {
    SessionOptions opts = o->session;
    if (o->centre.size() == 2) opts.centre_px = Eigen::Vector2d(o->centre[0], o->centre[1]);
    opts.validate();
    if (!(o->sphere_radius_mm >= 0 && o->sphere_radius_mm < 1000))
      throw InputError("", "--sphere-radius-mm", "expected the sphere's radius in mm (> 0)");
    const std::filesystem::path out_dir = std::filesystem::path(o->out).parent_path();
    if (!out_dir.empty() && !std::filesystem::is_directory(out_dir))
      throw InputError(o->out, "--out", "its folder does not exist", "create the folder first");
    const CameraModel camera = read_cameramodel(o->camera);
    const SessionAnalysis a = analyse_session(o->video, o->force_log, camera, opts);
    // Everything is computed before the first file is written.
    const std::string csv = presses_csv(a, opts.indenter_radius_mm, o->sphere_radius_mm);
    std::string json;
    std::vector<unsigned char> png;
    if (!o->report.empty()) {
      nlohmann::json j = report_json(a, opts);
      j["indenter"]["sphere_radius_mm"] = o->sphere_radius_mm > 0 ? nlohmann::json(o->sphere_radius_mm) : nlohmann::json(nullptr);
      json = j.dump(2) + "\n";
      if (!cv::imencode(".png", report_png(a, opts.indenter_radius_mm), png)) throw std::runtime_error("PNG encoding failed");
    }
    std::printf("%d frames at %.4g fps; %zu presses; clock offset %.4f +- %.4f s, drift %.1f +- %.1f ppm (%d events, correlation %.3f)\n",
                a.frames, a.fps, a.presses.size(), a.clock.offset_s, a.clock.offset_sigma_s, a.clock.drift * 1e6,
                a.clock.drift_sigma * 1e6, a.clock.events, a.clock.correlation);
    std::printf("indenter %s at (%.1f, %.1f) px, (%.2f, %.2f) mm on the skin, %.4f mm/px\n", a.centre_found ? "found" : "given",
                a.centre_px.x(), a.centre_px.y(), a.centre_mm.x(), a.centre_mm.y(), a.mm_per_px);
    for (const auto& w : a.warnings) std::cerr << "clearfit: warning: " << w << "\n";
    write_file_atomically(o->out, csv);
    std::printf("wrote %s\n", o->out.c_str());
    if (!o->report.empty()) {
      StagedFolder staged(o->report);  // the report folder swapped in whole
      write_file_atomically(staged.path() / "session.json", json);
      write_file_atomically(staged.path() / "session.png", std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
      staged.commit();
      std::printf("wrote %s/session.json, session.png\n", o->report.c_str());
    }
    return 0;
  };
}

static const Registration registered{"presses", 29, add_presses};

}  // namespace clearfit::cli
