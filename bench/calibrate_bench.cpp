// Calibration: clearfit (mrcal's optimizer from C++) side by side with
// mrcal-calibrate-cameras (Debian's python3-mrcal tool, on the same
// corners.vnl) and OpenCV's calibrateCamera (rational 8-parameter model) on
// the same corners: 30 views of a 10 x 10-corner board through a known
// OPENCV8 lens with Gaussian corner noise, several seeds. Prints per trial
// and a median row: wall time (and CPU time), time ratio, RMS (per
// coordinate, inlier corners), corners kept, and the projection error against
// the true lens: at the image centre, worst over the observed region, worst
// over the whole image (32 x 24 cells, camera-frame rotation fitted over the
// observed region as mrcal's projection_diff does).
//   calibrate_bench [trials=5] [noise_px=0.3] [lens=moderate|strong] [boards=whole|partial] [first_seed=100]
// whole: every view shows the whole board (what mrgingham's chessboards give);
// partial: views may be cut by the image border (at least half the corners in).
// The solves alone are compared in CPU seconds: clearfit's calibrate_camera (its seeding included) against
// mrcal's optimize calls inside mrcal-calibrate-cameras, and against those with its seed. Trial 0 is
// clearfit's first solve in the process (cold: libmrcal's solver then gets its memory fresh from the kernel,
// which costs page faults); the later trials are warm. `clearfit calibrate` runs one cold solve, so run
// single trials with different first seeds for the cold figure.
#include <clearfit/memory.hpp>
#include <clearfit/camera/calibrate.hpp>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

namespace {

using namespace clearfit;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// "strong": about 130 px of distortion in the image corners (the tests' lens);
// "moderate": about 50 px.
CameraModel true_lens(const std::string& kind) {
  CameraModel m;
  m.lensmodel = "LENSMODEL_OPENCV8";
  m.width = 1280;
  m.height = 960;
  if (kind == "strong")
    m.intrinsics = {1000.0, 1002.0, 641.3, 478.6, -0.30, 0.10, 0.0010, -0.0005, -0.02, 0.02, 0.01, 0.0};
  else
    m.intrinsics = {1000.0, 1002.0, 641.3, 478.6, -0.12, 0.03, 0.0005, -0.0003, 0.0, 0.01, 0.0, 0.0};
  return m;
}

double cpu_seconds(int who) {
  rusage u{};
  getrusage(who, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

struct Row {
  double wall = 0, cpu = 0, rms = 0, centre = 0, worst_observed = 0, worst_image = 0;
  int corners = 0;
  bool ok = false;
};

// Projection error against the truth on a 32 x 24 grid; `observed` marks the
// cells with corners (the rotation is fitted there).
void score(Row& row, const CameraModel& truth, const CameraModel& model, const std::vector<int>& observed) {
  const auto d = projection_difference_grid(truth, model, 32, 24, observed);
  row.worst_observed = row.worst_image = 0;
  for (std::size_t k = 0; k < d.size(); ++k) {
    const double e = std::isfinite(d[k]) ? d[k] : 1e9;
    row.worst_image = std::max(row.worst_image, e);
    if (observed[k]) row.worst_observed = std::max(row.worst_observed, e);
  }
  // The centre: the mean of the four cells around it.
  row.centre = 0.25 * (d[11 * 32 + 15] + d[11 * 32 + 16] + d[12 * 32 + 15] + d[12 * 32 + 16]);
}

// RMS per coordinate of a model over the given corners, each view's board pose
// from OpenCV (rvec, tvec) or ours.
double rms_of(const CameraModel& model, const std::vector<BoardObservation>& views, const CalibrationGrid& g,
              const std::vector<Rigid3>& poses, int* n_out) {
  double sum = 0;
  int n = 0;
  for (std::size_t v = 0; v < views.size(); ++v)
    for (int i = 0; i < g.height; ++i)
      for (int j = 0; j < g.width; ++j) {
        const auto& c = views[v].corners[static_cast<std::size_t>(i) * g.width + j];
        if (c.z() < 0) continue;
        const Vec2 q = model.project(poses[v].apply(Vec3(j * g.spacing_mm, i * g.spacing_mm, 0)));
        sum += (q - c.head<2>()).squaredNorm();
        ++n;
      }
  *n_out = n;
  return std::sqrt(sum / (2.0 * n));
}

std::string run(const std::string& command) {
  std::string out;
  FILE* p = popen((command + " 2>&1").c_str(), "r");
  if (!p) return out;
  char buf[4096];
  while (std::size_t n = fread(buf, 1, sizeof buf, p)) out.append(buf, n);
  if (pclose(p) != 0) out = "FAILED\n" + out;
  return out;
}

void print_row(const char* name, const Row& r, double ours_wall) {
  std::printf("  %-24s %8.3f %8.3f %7.2fx %8.4f %7d %9.4f %9.4f %11.4g\n", name, r.wall, r.cpu,
              r.wall / ours_wall, r.rms, r.corners, r.centre, r.worst_observed, r.worst_image);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

// Runs mrcal-calibrate-cameras (argv after the script) with its solve timed from inside: the CPU time
// (time.process_time, every thread) of its seed (mrcal.seed_stereographic, numpy) and of its mrcal.optimize
// calls (libmrcal, 4 of them), printed last as "mrcal seed cpu S optimize cpu O". The rest of its time is
// Python's start-up, imports, reading the corners and writing the model.
const char* const kTimedTool = R"(import runpy, sys, time
import mrcal
spent = {'seed': 0.0, 'optimize': 0.0}
def timed(name, f):
    def call(*args, **kwargs):
        t = time.process_time()
        try:
            return f(*args, **kwargs)
        finally:
            spent[name] += time.process_time() - t
    return call
mrcal.optimize = timed('optimize', mrcal.optimize)
mrcal.seed_stereographic = timed('seed', mrcal.seed_stereographic)
sys.argv = ['/usr/bin/mrcal-calibrate-cameras'] + sys.argv[1:]
try:
    runpy.run_path(sys.argv[0], run_name='__main__')
finally:
    print('mrcal seed cpu %.6f optimize cpu %.6f' % (spent['seed'], spent['optimize']))
)";

/// CPU seconds of mrcal's tool's seed and optimize calls (kTimedTool); NaN when it did not say.
struct MrcalSolveCpu {
  double seed = NAN, optimize = NAN;
};

/// mrcal's own tool on the same corners (a child process, timed as such, and its solve timed inside it);
/// its RMS from its optimization inputs.
Row mrcal_tool_row(const std::vector<BoardObservation>& views, const fs::path& dir, const CameraModel& truth,
                   const std::vector<int>& observed, MrcalSolveCpu& solve) {
  Row row;
  write_corners_levels_vnl(views, dir / "corners.vnl");
  fs::remove_all(dir / "mrcal");
  fs::create_directories(dir / "mrcal");
  std::ofstream(dir / "timed_tool.py") << kTimedTool;
  const double c0 = cpu_seconds(RUSAGE_CHILDREN);
  const auto t0 = Clock::now();
  const std::string out =
      run("cd " + dir.string() +
          " && /usr/bin/python3 timed_tool.py --corners-cache corners.vnl "
          "--lensmodel LENSMODEL_OPENCV8 --focal 1000 --imagersize 1280 960 --object-spacing 30 "
          "--object-width-n 10 --object-height-n 10 --outdir mrcal 'frame*.png'");
  row.wall = std::chrono::duration<double>(Clock::now() - t0).count();
  row.cpu = cpu_seconds(RUSAGE_CHILDREN) - c0;
  if (const std::size_t at = out.rfind("mrcal seed cpu "); at != std::string::npos)
    std::sscanf(out.c_str() + at, "mrcal seed cpu %lf optimize cpu %lf", &solve.seed, &solve.optimize);
  std::optional<CameraModel> tool;
  try {
    if (out.rfind("FAILED", 0) != 0)
      tool = read_cameramodel(dir / "mrcal" / "camera-0.cameramodel");
    else
      std::printf("  mrcal-calibrate-cameras failed:\n%s\n", out.c_str());
  } catch (const std::exception& e) {
    std::printf("  mrcal-calibrate-cameras wrote an unusable model: %s\n", e.what());
  }
  if (tool) {
    const CameraModel& m = *tool;
    // Its RMS per coordinate over its inliers, from its optimization_inputs
    // (it prints one decimal), outside the timing.
    const std::string stats = run(
        "cd " + dir.string() +
        " && /usr/bin/python3 -c \"import mrcal, numpy as np; m = "
        "mrcal.cameramodel('mrcal/camera-0.cameramodel'); "
        "oi = m.optimization_inputs(); x = mrcal.optimizer_callback(**oi)[1]; "
        "nb = mrcal.num_measurements_boards(**oi); w = oi['observations_board'][..., 2].ravel() >= 0; "
        "xb = x[:nb].reshape(-1, 2)[w]; print(np.sqrt(np.mean(xb * xb)), int(w.sum()))\"");
    std::sscanf(stats.substr(stats.find_last_of('\n', stats.size() - 2) + 1).c_str(), "%lf %d",
                &row.rms, &row.corners);
    row.ok = true;
    score(row, truth, m, observed);
  }
  return row;
}

/// OpenCV's calibrateCamera, rational model (k1 k2 p1 p2 k3 k4 k5 k6 = OPENCV8), on the same corners.
Row opencv_row(const std::vector<BoardObservation>& views, const CalibrationGrid& grid, const CameraModel& truth,
               const std::vector<int>& observed) {
  Row row;
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> image;
  for (const auto& v : views) {
    object.emplace_back();
    image.emplace_back();
    for (int i = 0; i < grid.height; ++i)
      for (int j = 0; j < grid.width; ++j) {
        const auto& c = v.corners[static_cast<std::size_t>(i) * grid.width + j];
        if (c.z() < 0) continue;
        object.back().emplace_back(float(j * grid.spacing_mm), float(i * grid.spacing_mm), 0.f);
        image.back().emplace_back(float(c.x()), float(c.y()));
      }
  }
  cv::Mat K, D;
  std::vector<cv::Mat> rvecs, tvecs;
  const double c0 = cpu_seconds(RUSAGE_SELF);
  const auto t0 = Clock::now();
  cv::calibrateCamera(object, image, cv::Size(1280, 960), K, D, rvecs, tvecs, cv::CALIB_RATIONAL_MODEL);
  row.wall = std::chrono::duration<double>(Clock::now() - t0).count();
  row.cpu = cpu_seconds(RUSAGE_SELF) - c0;
  CameraModel m;
  m.lensmodel = "LENSMODEL_OPENCV8";
  m.width = 1280;
  m.height = 960;
  m.intrinsics = {K.at<double>(0, 0), K.at<double>(1, 1), K.at<double>(0, 2), K.at<double>(1, 2)};
  for (int k = 0; k < 8; ++k) m.intrinsics.push_back(D.at<double>(k));
  std::vector<Rigid3> poses;
  for (std::size_t v = 0; v < views.size(); ++v) {
    Rigid3 p;
    p.rotation =
        rotation_from_rodrigues({rvecs[v].at<double>(0), rvecs[v].at<double>(1), rvecs[v].at<double>(2)});
    p.translation = {tvecs[v].at<double>(0), tvecs[v].at<double>(1), tvecs[v].at<double>(2)};
    poses.push_back(p);
  }
  row.rms = rms_of(m, views, grid, poses, &row.corners);
  row.ok = true;
  score(row, truth, m, observed);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  keep_freed_memory();  // as `clearfit calibrate` runs its solve (memory.hpp); mrcal's tool runs as shipped
  const int trials = argc > 1 ? std::atoi(argv[1]) : 5;
  const double noise = argc > 2 ? std::atof(argv[2]) : 0.3;
  const std::string lens = argc > 3 ? argv[3] : "moderate";
  const CameraModel truth = true_lens(lens);
  const bool whole = !(argc > 4 && std::string(argv[4]) == "partial");
  const unsigned first_seed = argc > 5 ? static_cast<unsigned>(std::atoi(argv[5])) : 100u;
  const CalibrationGrid grid{10, 10, 30.0};
  char templ[] = "/tmp/clearfit_calibrate_bench_XXXXXX";
  if (!mkdtemp(templ)) return 1;
  const fs::path dir = templ;
  double load[1] = {0};
  getloadavg(load, 1);
  std::printf(
      "calibration: 30 views of a 10 x 10 board (30 mm), OPENCV8 lens 1280x960 (%s: k1 %.2f), %s boards, "
      "noise %.2f px, %d trials, load average %.1f\n",
      lens.c_str(), truth.intrinsics[4], whole ? "whole" : "partial", noise, trials, load[0]);
  std::printf("  %-24s %8s %8s %8s %8s %7s %9s %9s %11s\n", "method", "wall s", "cpu s", "ratio", "rms px",
              "corners", "centre px", "worst obs", "worst image");
  std::vector<std::vector<Row>> all(4);
  std::vector<std::array<double, 3>> solves;  // per trial: clearfit, mrcal's optimize calls, with its seed
  const char* names[] = {"clearfit (solve)", "clearfit (+uncertainty)", "mrcal-calibrate-cameras",
                         "OpenCV calibrateCamera"};
  for (int t = 0; t < trials; ++t) {
    SyntheticViewsOptions o;
    o.views = 30;
    o.noise_px = noise;
    o.seed = first_seed + t;
    o.min_inside_fraction = whole ? 1.0 : 0.5;
    const auto views = synthesize_views(truth, grid, o);
    std::printf("trial %d (seed %u)\n", t, o.seed);
    std::vector<Row> rows(4);

    // clearfit, without and with the uncertainty.
    CalibrationResult ours;
    for (int k = 0; k < 2; ++k) {
      CalibrationOptions opt;
      opt.compute_uncertainty = k == 1;
      const double c0 = cpu_seconds(RUSAGE_SELF);
      const auto t0 = Clock::now();
      ours = calibrate_camera(views, grid, opt);
      rows[k].wall = std::chrono::duration<double>(Clock::now() - t0).count();
      rows[k].cpu = cpu_seconds(RUSAGE_SELF) - c0;
      rows[k].rms = ours.rms_px;
      rows[k].corners = ours.corners_used;
      rows[k].ok = true;
    }
    // The observed region: the cells of a 32 x 24 grid holding corners.
    std::vector<int> observed(32 * 24, 0);
    for (const auto& v : views)
      for (const auto& c : v.corners)
        if (c.z() >= 0)
          observed[std::clamp(int((c.y() + 0.5) / 960 * 24), 0, 23) * 32 +
                   std::clamp(int((c.x() + 0.5) / 1280 * 32), 0, 31)] = 1;
    score(rows[0], truth, ours.model, observed);
    score(rows[1], truth, ours.model, observed);

    MrcalSolveCpu mrcal_solve;
    rows[2] = mrcal_tool_row(views, dir, truth, observed, mrcal_solve);
    rows[3] = opencv_row(views, grid, truth, observed);
    for (int k = 0; k < 4; ++k) {
      if (rows[k].ok)
        print_row(names[k], rows[k], rows[0].wall);
      else
        std::printf("  %-24s failed (not in the medians)\n", names[k]);
      if (rows[k].ok) all[k].push_back(rows[k]);
    }
    // The solves alone, in CPU seconds: clearfit's calibrate_camera (its seed included) against mrcal's
    // optimize calls inside its tool, and against those with its seed (start-up and files left out).
    if (rows[2].ok && std::isfinite(mrcal_solve.seed) && std::isfinite(mrcal_solve.optimize)) {
      solves.push_back({rows[0].cpu, mrcal_solve.optimize, mrcal_solve.seed + mrcal_solve.optimize});
      std::printf("  solve cpu s: clearfit %.4f; mrcal's optimize calls %.4f (%.2fx), with its seed %.4f (%.2fx)\n",
                  rows[0].cpu, mrcal_solve.optimize, rows[0].cpu / mrcal_solve.optimize, solves.back()[2],
                  rows[0].cpu / solves.back()[2]);
    }
  }
  std::printf("median over %d trials\n", trials);
  const double ours_wall = median([&] {
    std::vector<double> v;
    for (auto& r : all[0]) v.push_back(r.wall);
    return v;
  }());
  for (int k = 0; k < 4; ++k) {
    Row m;
    std::vector<double> w, c, r, ce, wo, wi, n;
    for (const auto& row : all[k]) {
      w.push_back(row.wall);
      c.push_back(row.cpu);
      r.push_back(row.rms);
      ce.push_back(row.centre);
      wo.push_back(row.worst_observed);
      wi.push_back(row.worst_image);
      n.push_back(row.corners);
    }
    m = {median(w), median(c), median(r), median(ce), median(wo), median(wi), int(median(n)), true};
    print_row(names[k], m, ours_wall);
  }
  if (!solves.empty()) {
    std::vector<double> ours, opt, with_seed, r_opt, r_seed;
    for (const auto& t : solves) {
      ours.push_back(t[0]), opt.push_back(t[1]), with_seed.push_back(t[2]);
      r_opt.push_back(t[0] / t[1]), r_seed.push_back(t[0] / t[2]);
    }
    std::printf("  solve cpu s (medians of %zu trials): clearfit %.4f; mrcal's optimize calls %.4f, ratio %.2fx; "
                "with its seed %.4f, ratio %.2fx\n",
                solves.size(), median(ours), median(opt), median(r_opt), median(with_seed), median(r_seed));
    std::printf("  clearfit's first solve in this process (cold, trial 0): %.4f s, %.2fx mrcal's optimize calls\n",
                solves[0][0], solves[0][0] / solves[0][1]);
  }
  std::error_code ec;
  fs::remove_all(dir, ec);
  return 0;
}
