// clearfit calibrate-pressure: the per-person blanching → pressure calibration
// from calibration presses (known indenter, known force).
#include <clearfit/cli/commands.hpp>

#include <clearfit/atomic_file.hpp>
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/error.hpp>
#include <clearfit/fit/pressure_field_fit.hpp>
#include <clearfit/fit/pressure_model.hpp>
#include <clearfit/format.hpp>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

namespace clearfit::cli {

namespace {
constexpr double kStudyMeanR2 = 0.439;  // PAPER.md: the study's per-participant linear fits

nlohmann::json jnum(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

// Tick step of about range/target in {1, 2, 5}·10^k.
double nice_step(double range, int target) {
  const double raw = range / target, mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (raw <= m * mag) return m * mag;
  return 10 * mag;
}

// The fit as a chart: presses (outliers the robust fit rejected in red), the
// logistic curve, the study's linear line, the detection and saturation limits.
cv::Mat plot_fit(const PressureFitResult& r, const std::vector<CalibrationPress>& presses) {
  const int W = 900, H = 600, left = 90, right = 30, top = 50, bottom = 70;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  double p_hi = 0, y_lo = 0, y_hi = r.logistic.y_max;
  for (const auto& c : presses) {
    p_hi = std::max(p_hi, c.mean_pressure_kpa);
    y_lo = std::min(y_lo, c.signal);
    y_hi = std::max(y_hi, c.signal);
  }
  const double xs = nice_step(p_hi, 8), ys = nice_step(y_hi - y_lo, 6);
  const double x0 = 0, x1 = std::ceil(p_hi / xs) * xs, y0 = std::floor(y_lo / ys) * ys, y1 = std::ceil(y_hi / ys) * ys;
  auto px = [&](double p, double y) {
    return cv::Point(static_cast<int>(std::lround(left + (p - x0) / (x1 - x0) * (W - left - right))),
                     static_cast<int>(std::lround(H - bottom - (y - y0) / (y1 - y0) * (H - top - bottom))));
  };
  const cv::Scalar black(0, 0, 0), grey(200, 200, 200), blue(180, 90, 20), orange(0, 130, 240), red(40, 40, 220),
      green(60, 150, 40);
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  for (double t = x0; t <= x1 + 1e-9 * xs; t += xs) {
    cv::line(img, px(t, y0), px(t, y1), grey, 1);
    cv::line(img, px(t, y0), px(t, y0) + cv::Point(0, 6), black, 1);
    const std::string s = significant_digits(t, 3, "-");
    cv::putText(img, s, px(t, y0) + cv::Point(-4 * static_cast<int>(s.size()), 24), font, 0.45, black, 1, cv::LINE_AA);
  }
  for (double t = y0; t <= y1 + 1e-9 * ys; t += ys) {
    cv::line(img, px(x0, t), px(x1, t), grey, 1);
    cv::line(img, px(x0, t), px(x0, t) - cv::Point(6, 0), black, 1);
    const std::string s = significant_digits(std::abs(t) < 1e-12 ? 0.0 : t, 3, "-");
    cv::putText(img, s, px(x0, t) + cv::Point(-12 - 9 * static_cast<int>(s.size()), 5), font, 0.45, black, 1, cv::LINE_AA);
  }
  cv::rectangle(img, px(x0, y1), px(x1, y0), black, 1);
  cv::putText(img, "mean pressure (kPa)", cv::Point(W / 2 - 80, H - 20), font, 0.55, black, 1, cv::LINE_AA);
  cv::putText(img, "signal y", cv::Point(10, top - 20), font, 0.55, black, 1, cv::LINE_AA);
  // Limits of the stored calibration (dotted).
  const PressureCalibration& cal = r.calibration;
  for (double lim : {cal.detection_signal(), cal.saturation_signal()})
    if (lim > y0 && lim < y1)
      for (double p = x0; p < x1; p += (x1 - x0) / 90) cv::line(img, px(p, lim), px(std::min(x1, p + (x1 - x0) / 180), lim), grey * 0.6, 1);
  // Curves.
  std::vector<cv::Point> curve;
  for (int k = 0; k <= 400; ++k) {
    const double p = x0 + (x1 - x0) * k / 400;
    curve.push_back(px(p, logistic_signal(r.logistic, p)));
  }
  cv::polylines(img, curve, false, green, 2, cv::LINE_AA);
  const double la = r.linear.intercept, lb = r.linear.slope_per_kpa;
  for (int k = 0; k < 60; k += 2) {  // dashed, inside the axes only
    const double pa = x0 + (x1 - x0) * k / 60, pb = x0 + (x1 - x0) * (k + 1) / 60;
    const double ya = la + lb * pa, yb = la + lb * pb;
    if (std::min(ya, yb) >= y0 && std::max(ya, yb) <= y1) cv::line(img, px(pa, ya), px(pb, yb), orange, 2, cv::LINE_AA);
  }
  // Legend.
  const cv::Point lg(W - right - 10 - 380, H - bottom - 10 - 80);  // bottom right: empty for a sigmoid
  cv::rectangle(img, lg + cv::Point(-12, -14), lg + cv::Point(380, 80), cv::Scalar(255, 255, 255), cv::FILLED);
  cv::rectangle(img, lg + cv::Point(-12, -14), lg + cv::Point(380, 80), grey, 1);
  cv::circle(img, lg, 4, blue, cv::FILLED, cv::LINE_AA);
  cv::putText(img, "presses (x: outliers)", lg + cv::Point(15, 5), font, 0.45, black, 1, cv::LINE_AA);
  cv::line(img, lg + cv::Point(-8, 22), lg + cv::Point(8, 22), green, 2);
  cv::putText(img, "logistic, R2 = " + significant_digits(r.r2_logistic, 3, "-"), lg + cv::Point(15, 27),
              font, 0.45, black, 1, cv::LINE_AA);
  cv::line(img, lg + cv::Point(-8, 44), lg + cv::Point(8, 44), orange, 2);
  cv::putText(img, "linear, R2 = " + significant_digits(r.linear.r2, 3, "-") + " (study mean 0.439)",
              lg + cv::Point(15, 49), font, 0.45, black, 1, cv::LINE_AA);
  cv::putText(img, "dotted: detection limit, saturation", lg + cv::Point(15, 71), font, 0.45, black, 1, cv::LINE_AA);
  // Presses.
  for (std::size_t i = 0; i < presses.size(); ++i) {
    const cv::Point c = px(presses[i].mean_pressure_kpa, presses[i].signal);
    if (r.residuals[i].weight < 0.5) {
      cv::line(img, c + cv::Point(-5, -5), c + cv::Point(5, 5), red, 2, cv::LINE_AA);
      cv::line(img, c + cv::Point(-5, 5), c + cv::Point(5, -5), red, 2, cv::LINE_AA);
    } else {
      cv::circle(img, c, 4, blue, cv::FILLED, cv::LINE_AA);
    }
  }
  return img;
}

nlohmann::json report_json(const PressureFitResult& r, const std::string& presses_path, const std::string& camera_path,
                           const std::string& out) {
  using nlohmann::json;
  const PressureCalibration& cal = r.calibration;
  json residuals = json::array();
  for (const auto& pr : r.residuals)
    residuals.push_back({{"trial", pr.trial}, {"pressure_kpa", pr.pressure_kpa}, {"signal", pr.signal},
                         {"residual_signal", pr.residual_signal}, {"residual_signal_linear", pr.residual_linear},
                         {"predicted_kpa", jnum(pr.predicted_kpa)}, {"residual_kpa", jnum(pr.residual_kpa)},
                         {"weight", pr.weight}, {"status", to_string(pr.status)}});
  const PressureEstimate det = cal.invert(cal.detection_signal(), 0.0), sat = cal.invert(1e300);
  return {{"schema", "clearfit.pressure-calibration-report/1"},
          {"inputs", {{"presses", presses_path}, {"person", cal.person},
                      {"camera", camera_path.empty() ? json(nullptr) : json(camera_path)},
                      {"camera_intrinsics_hash", cal.camera_hash.empty() ? json(nullptr) : json(cal.camera_hash)}}},
          {"calibration", out},
          {"model", to_string(cal.model)},
          {"presses", cal.presses},
          {"levels", r.levels},
          {"pressure_range_kpa", {cal.p_min_kpa, cal.p_max_kpa}},
          {"logistic", {{"y_max", r.logistic.y_max}, {"p50_kpa", r.logistic.p50_kpa}, {"width_kpa", r.logistic.width_kpa},
                        {"standard_errors", {{"y_max", r.logistic_se[0]}, {"p50_kpa", r.logistic_se[1]}, {"width_kpa", r.logistic_se[2]}}},
                        {"r2", jnum(r.r2_logistic)}, {"converged", r.converged}, {"iterations", r.iterations}}},
          {"linear", {{"intercept", r.linear.intercept}, {"slope_per_kpa", r.linear.slope_per_kpa},
                      {"standard_errors", {{"intercept", r.linear.se_intercept}, {"slope_per_kpa", r.linear.se_slope}}},
                      {"r2", jnum(r.linear.r2)}, {"study_mean_r2", kStudyMeanR2}}},
          {"noise_sigma", cal.noise_sigma},
          {"limits", {{"detection_signal", cal.detection_signal()},
                      {"detection_kpa", jnum(det.status == PressureStatus::ok ? det.pressure_kpa : det.bound_kpa)},
                      {"saturation_signal", cal.saturation_signal()}, {"saturation_kpa", jnum(sat.bound_kpa)}}},
          {"rmse_kpa", jnum(r.rmse_kpa)},
          {"presses_in_range", r.presses_in_range},
          {"rmse_kpa_without_outliers", jnum(r.rmse_kpa_inliers)},
          {"residuals", residuals},
          {"warnings", r.warnings}};
}

/// `fitted`: what the RMSE counts ("presses", or "rings" for a field fit: each press's rings of the radial profile).
void print_summary(const PressureFitResult& r, RobustLoss loss, const char* fitted) {
  const PressureCalibration& cal = r.calibration;
  std::printf("person %s: %d presses at %d pressure levels, %s..%s kPa; robust loss %s\n", cal.person.c_str(),
              cal.presses, r.levels, significant_digits(cal.p_min_kpa, 3, "-").c_str(),
              significant_digits(cal.p_max_kpa, 3, "-").c_str(), to_string(loss));
  std::printf("\n  %-9s %-14s %12s %12s\n", "model", "parameter", "value", "+- SE");
  auto row = [](const char* model, const char* name, double v, double se) {
    std::printf("  %-9s %-14s %12s %12s\n", model, name, significant_digits(v, 5, "-").c_str(),
                significant_digits(se, 3, "-").c_str());
  };
  row("logistic", "y_max", r.logistic.y_max, r.logistic_se[0]);
  row("", "p50_kpa", r.logistic.p50_kpa, r.logistic_se[1]);
  row("", "width_kpa", r.logistic.width_kpa, r.logistic_se[2]);
  row("linear", "intercept", r.linear.intercept, r.linear.se_intercept);
  row("", "slope_per_kpa", r.linear.slope_per_kpa, r.linear.se_slope);
  const PressureEstimate det = cal.invert(cal.detection_signal(), 0.0), sat = cal.invert(1e300);
  std::printf("\n  R^2 of the signal: logistic %s, linear %s (the study's linear fits: mean %.3f)\n",
              significant_digits(r.r2_logistic, 3, "-").c_str(),
              significant_digits(r.linear.r2, 3, "-").c_str(), kStudyMeanR2);
  std::printf(
      "  stored model: %s; RMSE %s kPa over %d %s inside the invertible range (%s kPa without "
      "outliers)\n",
      to_string(cal.model), significant_digits(r.rmse_kpa, 3, "-").c_str(), r.presses_in_range, fitted,
      significant_digits(r.rmse_kpa_inliers, 3, "-").c_str());
  std::printf(
      "  signal noise %s: detection limit %s (%s kPa), saturation %s (%s kPa)\n",
      significant_digits(cal.noise_sigma, 3, "-").c_str(),
      significant_digits(cal.detection_signal(), 3, "-").c_str(),
      significant_digits(det.status == PressureStatus::ok ? det.pressure_kpa : det.bound_kpa, 3, "-").c_str(),
      significant_digits(cal.saturation_signal(), 3, "-").c_str(),
      significant_digits(sat.bound_kpa, 3, "-").c_str());
  std::printf("\n  %-8s %8s %9s %10s %10s %9s %8s %6s  %s\n", "trial", "p_kpa", "signal", "res", "res_lin", "pred_kpa",
              "res_kpa", "weight", "status");
  for (std::size_t i = 0; i < r.residuals.size(); ++i) {
    const PressResidual& pr = r.residuals[i];
    std::printf("  %-8s %8s %9s %10s %10s %9s %8s %6s  %s\n", pr.trial.c_str(),
                significant_digits(pr.pressure_kpa, 4, "-").c_str(),
                significant_digits(pr.signal, 4, "-").c_str(),
                significant_digits(pr.residual_signal, 3, "-").c_str(),
                significant_digits(pr.residual_linear, 3, "-").c_str(),
                significant_digits(pr.predicted_kpa, 4, "-").c_str(),
                significant_digits(pr.residual_kpa, 3, "-").c_str(),
                significant_digits(pr.weight, 2, "-").c_str(), to_string(pr.status));
  }
  std::printf("\n");
}
}  // namespace

Run add_calibrate_pressure(CLI::App& app) {
  struct Opts {
    std::string presses, person, camera, out, model = "logistic", loss = "tukey", report, plot, field;
    FieldFitOptions field_fit;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand(
      "calibrate-pressure",
      "Per-person blanching -> pressure calibration from presses with known force (logistic model, robust fit)");
  sub->add_option("--presses", o->presses,
                  "Presses CSV: header trial,indenter_diameter_mm,force_n,mean_pressure_kpa,signal (mean_pressure_kpa may be "
                  "left empty: force / (pi r^2))")->required();
  sub->add_option("--person", o->person, "Who was calibrated (the scene's person must match)")->required();
  sub->add_option("--camera", o->camera, "Camera model (.cameramodel) the signal was measured with; scenes with another camera are refused");
  sub->add_option("--out", o->out, "Output calibration file (JSON, clearfit.pressure-calibration/1)")->required();
  sub->add_option("--model", o->model, "Model stored in the calibration (both are always fitted and reported)")
      ->check(CLI::IsMember({"logistic", "linear"}))->capture_default_str();
  sub->add_option("--loss", o->loss, "Robust loss of the logistic fit")->check(CLI::IsMember({"tukey", "huber", "none"}))->capture_default_str();
  sub->add_option("--pressure-field", o->field,
                  "Pressure under the indenter: punch (Sneddon's flat punch, blurred; fitted to the presses' radial profiles), "
                  "hertz (a sphere: Hertz's pressure over the contact radius of each force, blurred; presses with sphere_radius_mm) or "
                  "uniform (F/(pi a^2) against the disc's mean signal, as the study); default hertz or punch when the presses carry "
                  "profiles")
      ->check(CLI::IsMember({"punch", "hertz", "uniform"}));
  sub->add_option("--skin-blur-mm,--blur-mm", o->field_fit.skin_blur_mm,
                  "The skin's lateral blur of the pressure (Gaussian sigma, punch and hertz fields), mm; written into the calibration, "
                  "whose assessments undo the same blur (assess's --skin-blur-mm, scene key assess.skin_blur_mm)")->capture_default_str();
  sub->add_option("--e-star-kpa", o->field_fit.e_star_kpa,
                  "The skin's plane-strain modulus E* for the hertz field, kPa (0: fitted with the calibration)")->capture_default_str();
  sub->add_option("--report", o->report, "Output report (JSON): parameters, SE, R^2, RMSE, residuals per trial, warnings");
  sub->add_option("--plot", o->plot, "Output PNG of the fit: presses, logistic curve, linear line");

  return [o]() {
    if (o->person.empty() || std::any_of(o->person.begin(), o->person.end(), [](unsigned char c) { return c < 0x20; }))
      throw InputError("", "--person", "must be a non-empty name without control characters");
    // Outputs must not overwrite the input or each other; their folders must exist.
    std::vector<std::pair<std::string, std::string>> outputs{{"--out", o->out}};
    if (!o->report.empty()) outputs.emplace_back("--report", o->report);
    if (!o->plot.empty()) outputs.emplace_back("--plot", o->plot);
    for (std::size_t i = 0; i < outputs.size(); ++i) {
      const std::filesystem::path path = outputs[i].second;
      const std::filesystem::path dir = path.parent_path().empty() ? "." : path.parent_path();
      if (!std::filesystem::is_directory(dir))
        throw InputError(outputs[i].second, outputs[i].first,
                         std::filesystem::exists(dir) ? dir.string() + " is a file, not a folder" : "its folder does not exist",
                         "create the folder first");
      std::error_code ec;
      if (std::filesystem::equivalent(path, o->presses, ec))
        throw InputError(outputs[i].second, outputs[i].first, "would overwrite the presses file");
      for (std::size_t j = 0; j < i; ++j)
        if (std::filesystem::weakly_canonical(path) == std::filesystem::weakly_canonical(outputs[j].second))
          throw InputError(outputs[i].second, outputs[i].first, "is the same file as " + outputs[j].first);
    }
    std::vector<std::string> notes;
    const std::vector<CalibrationPress> presses = read_presses_csv(o->presses, &notes);
    for (const auto& n : notes) std::cerr << "clearfit: note: " << n << "\n";
    PressureFitOptions fo;
    fo.person = o->person;
    fo.model = o->model == "linear" ? PressureModelKind::linear : PressureModelKind::logistic;
    fo.loss = o->loss == "none" ? RobustLoss::none : o->loss == "huber" ? RobustLoss::huber : RobustLoss::tukey;
    fo.source = o->presses;
    if (!o->camera.empty()) fo.camera_hash = format_intrinsics_hash(read_cameramodel(o->camera).intrinsics_hash());
    const bool profiles = presses_have_profiles(presses);
    const bool spheres = std::all_of(presses.begin(), presses.end(), [](const auto& c) { return std::isfinite(c.sphere_radius_mm); });
    const std::string field = !o->field.empty() ? o->field : !profiles ? "uniform" : spheres ? "hertz" : "punch";
    if (field != "uniform" && fo.model == PressureModelKind::linear)
      throw InputError("", "--model linear", "is fitted to the disc's mean signal only", "use --pressure-field uniform with it");
    FieldFitOptions ff = o->field_fit;
    ff.field = field == "hertz" ? PressureField::hertz : PressureField::punch;
    const PressureFitResult r = field != "uniform" ? fit_pressure_field(presses, fo, ff) : fit_pressure_calibration(presses, fo);
    // The points drawn: the presses (uniform), or every ring at its mean blurred pressure (punch, hertz).
    std::vector<CalibrationPress> points = presses;
    PressureFitResult drawn = r;
    if (field != "uniform") {
      points.clear(), drawn.residuals.clear();
      for (const CalibrationPress& c : presses) {
        const std::vector<double> drive = ring_drives_kpa(c, ff, r.e_star_kpa);
        for (std::size_t k = 0; k < c.ring_signal.size(); ++k) {
          CalibrationPress ring = c;
          ring.mean_pressure_kpa = drive[k];
          ring.signal = c.ring_signal[k];
          points.push_back(ring);
          drawn.residuals.push_back({});
        }
      }
    }

    // Everything is computed before the first file is written.
    std::string report;
    if (!o->report.empty()) {
      nlohmann::json j = report_json(r, o->presses, o->camera, o->out);
      j["pressure_field"] = {{"kind", field}, {"skin_blur_mm", field != "uniform" ? jnum(ff.skin_blur_mm) : jnum(NAN)},
                             {"e_star_kpa", jnum(r.e_star_kpa)}, {"e_star_se_kpa", jnum(r.e_star_se_kpa)},
                             {"e_star_fitted", field == "hertz" && ff.e_star_kpa == 0}};
      report = j.dump(2) + "\n";
    }
    std::vector<unsigned char> png;
    if (!o->plot.empty() && !cv::imencode(".png", plot_fit(drawn, points), png))
      throw std::runtime_error("PNG encoding of the fit plot failed");
    print_summary(r, fo.loss, field == "uniform" ? "presses" : "rings");
    if (field == "hertz")
      std::printf("pressure field: hertz (a sphere: Hertz's pressure over each force's contact radius, blurred; the presses' radial "
                  "profiles); E* %s +- %s kPa (%s)\n", significant_digits(r.e_star_kpa, 4, "-").c_str(), significant_digits(r.e_star_se_kpa, 3, "-").c_str(),
                  ff.e_star_kpa == 0 ? "fitted" : "given");
    else
      std::printf("pressure field: %s%s\n", field.c_str(), field == "punch" ? " (Sneddon's flat punch, blurred; the presses' radial profiles)" : " (F / pi a^2)");
    std::fflush(stdout);
    for (const auto& w : r.warnings) std::cerr << "clearfit: warning: " << w << "\n";
    write_pressure_calibration(r.calibration, o->out);
    std::printf("wrote %s\n", o->out.c_str());
    if (!o->report.empty()) {
      write_file_atomically(o->report, report);
      std::printf("wrote %s\n", o->report.c_str());
    }
    if (!o->plot.empty()) {
      write_file_atomically(o->plot, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
      std::printf("wrote %s\n", o->plot.c_str());
    }
    return 0;
  };
}

static const Registration registered{"calibrate-pressure", 30, add_calibrate_pressure};

}  // namespace clearfit::cli
