// clearfit-bench map: run time against error of the refraction map's modes
// (exact, grid, adaptive) on the analytic parts, against the exact trace and
// against the floor of two batched ray casts per pixel measured in the same run
// (with clearfit's ray index, and with plain Embree packets: embree_floor.hpp).
#include "embree_floor.hpp"
#include "map_scenes.hpp"

#include <clearfit/cli/commands.hpp>

#include <clearfit/atomic_file.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/error.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <malloc.h>
#include <cstdio>
#include <iostream>
#include <sstream>

namespace clearfit::cli {

namespace {

struct Size {
  int w, h;
  std::string label() const { return std::to_string(w) + "x" + std::to_string(h); }
};

struct ModeSpec {
  std::string label;  // "exact", "grid:8", "adaptive:1"
  MapOptions::Mode mode = MapOptions::Mode::exact;
  int step = MapOptions{}.grid_step;
  double tol_um = 1;
};

struct Row {
  std::string shape, size, mode;
  int triangles = 0;
  MapOptions::Mode kind = MapOptions::Mode::exact;
  double param = 0;
  double emb_ms = 0, emb_build_ms = 0, emb_cpu_ms = 0, index_ms = 0;  // Embree floor: casts, BVH, CPU; clearfit's index build
  double ms = 0, trace_ms = 0, floor_ms = 0, floor_recast_ms = 0, cpu_ms = 0, floor_cpu_ms = 0, exact_cpu_ms = 0, exact_ms = 0, first_ms = 0, unproject_ms = 0;
  long long traced = 0, interpolated = 0, valid = 0, pixels = 0;
  double coverage = 0, est_max_um = 0;
  bench::MapError err;
};

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  for (std::string item; std::getline(in, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

std::string join(const std::vector<std::string>& items) {
  std::string s;
  for (const std::string& item : items) s += (s.empty() ? "" : ",") + item;
  return s;
}

std::vector<Size> parse_sizes(const std::string& s) {
  std::vector<Size> out;
  for (const std::string& item : split(s)) {
    Size z{};
    char x = 0, extra = 0;
    if (std::sscanf(item.c_str(), "%d%c%d%c", &z.w, &x, &z.h, &extra) != 3 || (x != 'x' && x != 'X') || z.w < 16 ||
        z.h < 16 || z.w > 16384 || z.h > 16384)
      throw InputError("", "--sizes '" + item + "'", "is not WIDTHxHEIGHT with 16..16384 pixels each", "e.g. 1920x1080");
    out.push_back(z);
  }
  if (out.empty()) throw InputError("", "--sizes", "is empty", "e.g. 640x480,1920x1080");
  return out;
}

std::vector<ModeSpec> parse_modes(const std::string& s) {
  std::vector<ModeSpec> out;
  for (const std::string& item : split(s)) {
    ModeSpec m;
    m.label = item;
    const auto colon = item.find(':');
    const std::string kind = item.substr(0, colon), arg = colon == std::string::npos ? "" : item.substr(colon + 1);
    try {
      std::size_t used = 0;
      if (kind == "exact" && arg.empty()) {
        m.mode = MapOptions::Mode::exact;
      } else if (kind == "grid" && !arg.empty()) {
        m.mode = MapOptions::Mode::grid;
        m.step = std::stoi(arg, &used);
      } else if (kind == "adaptive" && !arg.empty()) {
        m.mode = MapOptions::Mode::adaptive;
        m.tol_um = std::stod(arg, &used);
        m.step = MapOptions{}.grid_step;  // the quadtree's starting cell (MapOptions' default)
      } else {
        used = std::string::npos;
      }
      if (used != arg.size()) throw std::invalid_argument("trailing characters");
      MapOptions probe;
      probe.mode = m.mode;
      probe.grid_step = m.step;
      probe.tolerance_um = m.tol_um;
      probe.validate();
    } catch (const std::exception& e) {
      throw InputError("", "--modes '" + item + "'", std::string("is not a mode: ") + e.what(),
                       "exact, grid:STEP (a power of two 2..256) or adaptive:TOLERANCE_UM (> 0)");
    }
    out.push_back(m);
  }
  if (out.empty()) throw InputError("", "--modes", "is empty", "e.g. exact,grid:8,adaptive:1");
  return out;
}

std::string csv_text(const std::vector<Row>& rows, int repeat) {
  std::ostringstream o;
  o.precision(6);
  o << "shape,width,height,triangles,mode,param,time_ms,trace_ms,floor_ms,ratio_to_floor,speedup_vs_exact,"
       "first_map_ms,first_unproject_ms,pixels,traced,interpolated,valid,coverage,median_um,p99_um,max_um,estimated_max_um,"
       "validity_diff,reason_diff,repeat,floor_recast_ms\n";
  for (const Row& r : rows) {
    const auto x = r.size.find('x');
    o << r.shape << ',' << r.size.substr(0, x) << ',' << r.size.substr(x + 1) << ',' << r.triangles << ','
      << (r.kind == MapOptions::Mode::exact ? "exact" : r.kind == MapOptions::Mode::grid ? "grid" : "adaptive") << ','
      << r.param << ',' << r.ms << ',' << r.trace_ms << ',' << r.floor_ms << ',' << r.ms / r.floor_ms << ','
      << r.exact_ms / r.ms << ',' << r.first_ms << ',' << r.unproject_ms << ',' << r.pixels << ',' << r.traced << ',' << r.interpolated
      << ',' << r.valid << ',' << r.coverage << ',' << r.err.median_um << ',' << r.err.p99_um << ',' << r.err.max_um
      << ',' << r.est_max_um << ',' << r.err.validity_diff << ',' << r.err.reason_diff << ',' << repeat << ',' << r.floor_recast_ms << '\n';
  }
  return o.str();
}

// The part and the posed camera as files, and the command that maps them.
void export_part(const std::string& dir, const bench::Scene& scene, CameraModel camera, const Rigid3& pose,
                 const std::string& size) {
  std::string stem = scene.name;
  std::replace(stem.begin(), stem.end(), ':', '-');
  const std::filesystem::path mesh = std::filesystem::path(dir) / (stem + ".obj");
  const std::filesystem::path cam = std::filesystem::path(dir) / (stem + "_" + size + ".cameramodel");
  std::filesystem::create_directories(dir);
  if (!std::filesystem::exists(mesh)) save_mesh(scene.mesh, mesh);
  camera.cam_from_part = pose;
  write_cameramodel(camera, cam);
  std::cerr << "bench: exported; whole process: clearfit map --mesh " << mesh.string() << " --camera " << cam.string()
            << " --contact-group contact --no-cache --out " << (std::filesystem::path(dir) / (stem + "_" + size + ".npy")).string()
            << "\n";
}

void print_table(const std::vector<Row>& rows) {
  std::printf("%-6s %-9s %-12s %8s %6s %8s %6s %6s %6s %6s %6s %6s %8s %8s %6s %9s %9s %9s %6s %6s %6s\n", "shape", "size", "mode", "time_ms",
              "xfloor", "floor_ms", "xfl_rc", "emb_ms", "xemb", "speed", "cpu_xf", "cpu_sp", "first_ms", "unproj", "traced", "median_um", "p99_um", "max_um", "vdiff",
              "rdiff", "cover");
  std::string last;
  for (const Row& r : rows) {
    if (!last.empty() && last != r.shape + r.size) std::printf("\n");
    last = r.shape + r.size;
    std::printf("%-6s %-9s %-12s %8.1f %6.2f %8.1f %6.2f %6.1f %6.2f %5.1fx %6.2f %5.1fx %8.1f %8.1f %5.1f%% %9.3g %9.3g %9.3g %6lld %6lld %5.1f%%\n",
                r.shape.c_str(), r.size.c_str(), r.mode.c_str(), r.ms, r.ms / r.floor_ms, r.floor_ms,
                r.ms / r.floor_recast_ms, r.emb_ms, r.ms / r.emb_ms, r.exact_ms / r.ms, r.cpu_ms / r.floor_cpu_ms, r.exact_cpu_ms / r.cpu_ms,
                r.first_ms, r.unproject_ms, 100.0 * r.traced / std::max(1LL, r.pixels), r.err.median_um, r.err.p99_um,
                r.err.max_um, r.err.validity_diff, r.err.reason_diff, 100 * r.coverage);
  }
  std::printf("\nexact map cold (ray index build + the first exact map, its unprojection included) against the Embree\n"
              "floor (BVH build + two rtcIntersect16 per pixel and per seen-outline ray), wall clock; and warm in CPU\n"
              "time (the exact map with its index built and its rays unprojected, against the floor's two casts):\n");
  last.clear();
  for (const Row& r : rows) {
    if (last == r.shape + r.size || r.kind != MapOptions::Mode::exact) continue;
    last = r.shape + r.size;
    const double cold = r.index_ms + r.first_ms, floor = r.emb_build_ms + r.emb_ms;
    std::printf("%-6s %-9s index %7.1f + map %7.1f (unproject %7.1f) = %7.1f ms; floor BVH %6.1f + casts %6.1f = %6.1f ms; "
                "%5.2fx (%5.2fx without unprojection); CPU warm %7.1f / casts %7.1f ms = %5.2fx\n",
                r.shape.c_str(), r.size.c_str(), r.index_ms, r.first_ms, r.unproject_ms, cold, r.emb_build_ms, r.emb_ms,
                floor, cold / floor, (cold - r.unproject_ms) / floor, r.cpu_ms, r.emb_cpu_ms, r.cpu_ms / r.emb_cpu_ms);
  }
}

// The table's legend: what each column means.
void print_legend(int repeat, bool fresh_memory, const std::string& chart) {
  std::printf("# refraction map, best of %d runs per case (wall clock ms, all threads)%s, chart %s\n"
              "# xfloor = time / floor (2 batched ray casts per traced pixel, the second skipping the entry face);\n"
              "#   xfl_rc = time / the floor with Embree's re-cast of refracted rays that re-find their entry face\n"
              "# emb_ms = plain Embree floor's two rtcIntersect16 casts per pixel (4x4 tiles, all cores, BVH prebuilt\n"
              "#   like the maps' index) and per ray of the seen outline (4x4 per outline pixel); xemb = time / emb_ms\n"
              "# speed = exact time / time; cpu_xf, cpu_sp: the same ratios in process CPU time (all threads,\n"
              "#   best of the runs; steadier than wall time when other processes share the cores)\n"
              "# first_ms = the first (exact) map of the shape and size, with the unprojection (unproj) of its\n"
              "#   pixels; the later maps reuse the cached rays\n"
              "# errors: |skin point - exact| over pixels valid in both; vdiff = pixels valid in only one;\n"
              "#   rdiff = pixels invalid in both for different reasons (adaptive/grid: nearest node's reason where two\n"
              "#   invalid reasons meet)\n",
              repeat, fresh_memory ? ", fresh memory" : "", chart.c_str());
}

// Log-log plot of time (ms) against the p99 error (µm), one colour per
// shape/size; squares exact (drawn at the left edge: error 0), circles grid,
// triangles adaptive; a dash at the left edge marks each series' floor.
cv::Mat plot(const std::vector<Row>& rows) {
  const int W = 1400, H = 900, left = 90, right = 330, top = 50, bottom = 80;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  double emin = 1e300, emax = 0, tmin = 1e300, tmax = 0;
  for (const Row& r : rows) {
    if (r.err.p99_um > 0) emin = std::min(emin, r.err.p99_um), emax = std::max(emax, r.err.p99_um);
    tmin = std::min({tmin, r.ms, r.floor_ms});
    tmax = std::max({tmax, r.ms, r.floor_ms});
  }
  if (emax <= 0) emin = 1e-3, emax = 1;
  const double ex0 = std::floor(std::log10(emin)) - 1, ex1 = std::ceil(std::log10(emax));  // one decade for "exact"
  const double ty0 = std::floor(std::log10(tmin)), ty1 = std::ceil(std::log10(tmax));
  auto px = [&](double e) {
    const double l = e > 0 ? std::max(std::log10(e), ex0) : ex0;
    return left + static_cast<int>((l - ex0) / (ex1 - ex0) * (W - left - right));
  };
  auto py = [&](double t) { return H - bottom - static_cast<int>((std::log10(t) - ty0) / (ty1 - ty0) * (H - top - bottom)); };
  const cv::Scalar black(0, 0, 0), grey(215, 215, 215);
  const auto font = cv::FONT_HERSHEY_SIMPLEX;
  for (int d = static_cast<int>(ex0); d <= static_cast<int>(ex1); ++d) {
    const int x = px(std::pow(10.0, d));
    cv::line(img, {x, top}, {x, H - bottom}, grey, 1);
    cv::putText(img, d == static_cast<int>(ex0) ? "0" : "1e" + std::to_string(d), {x - 18, H - bottom + 22}, font, 0.5, black, 1, cv::LINE_AA);
  }
  for (int d = static_cast<int>(ty0); d <= static_cast<int>(ty1); ++d) {
    const int y = py(std::pow(10.0, d));
    cv::line(img, {left, y}, {W - right, y}, grey, 1);
    cv::putText(img, "1e" + std::to_string(d), {left - 45, y + 5}, font, 0.5, black, 1, cv::LINE_AA);
  }
  cv::rectangle(img, {left, top}, {W - right, H - bottom}, black, 1);
  cv::putText(img, "p99 error against the exact trace (um, log)", {left + 250, H - 25}, font, 0.6, black, 1, cv::LINE_AA);
  cv::putText(img, "refraction map: time (ms, log) against error", {left, 30}, font, 0.7, black, 2, cv::LINE_AA);
  cv::Mat ylabel(30, 260, CV_8UC3, cv::Scalar(255, 255, 255));
  cv::putText(ylabel, "time per map (ms, log)", {5, 20}, font, 0.6, black, 1, cv::LINE_AA);
  cv::rotate(ylabel, ylabel, cv::ROTATE_90_COUNTERCLOCKWISE);
  ylabel.copyTo(img(cv::Rect(5, top + 150, ylabel.cols, ylabel.rows)));

  static const cv::Scalar palette[] = {{180, 119, 31}, {14, 127, 255}, {44, 160, 44}, {40, 39, 214}, {189, 103, 148},
                                       {75, 86, 140},  {194, 119, 227}, {127, 127, 127}, {34, 189, 188}, {207, 190, 23},
                                       {0, 0, 0},      {128, 0, 128}};
  std::vector<std::string> series;
  for (const Row& r : rows)
    if (std::find(series.begin(), series.end(), r.shape + " " + r.size) == series.end()) series.push_back(r.shape + " " + r.size);
  auto marker = [&](MapOptions::Mode kind, cv::Point p, const cv::Scalar& c) {
    if (kind == MapOptions::Mode::exact) cv::rectangle(img, p - cv::Point(5, 5), p + cv::Point(5, 5), c, cv::FILLED);
    else if (kind == MapOptions::Mode::grid) cv::circle(img, p, 5, c, cv::FILLED, cv::LINE_AA);
    else {
      const std::vector<cv::Point> tri = {p + cv::Point(0, -7), p + cv::Point(6, 4), p + cv::Point(-6, 4)};
      cv::fillConvexPoly(img, tri, c, cv::LINE_AA);
    }
  };
  for (std::size_t s = 0; s < series.size(); ++s) {
    const cv::Scalar c = palette[s % std::size(palette)];
    for (MapOptions::Mode kind : {MapOptions::Mode::grid, MapOptions::Mode::adaptive}) {
      std::vector<const Row*> pts;
      for (const Row& r : rows)
        if (r.shape + " " + r.size == series[s] && r.kind == kind) pts.push_back(&r);
      std::sort(pts.begin(), pts.end(), [](const Row* a, const Row* b) { return a->param < b->param; });
      for (std::size_t k = 1; k < pts.size(); ++k)
        cv::line(img, {px(pts[k - 1]->err.p99_um), py(pts[k - 1]->ms)}, {px(pts[k]->err.p99_um), py(pts[k]->ms)}, c, 1, cv::LINE_AA);
    }
    for (const Row& r : rows)
      if (r.shape + " " + r.size == series[s]) {
        marker(r.kind, {px(r.err.p99_um), py(r.ms)}, c);
        cv::line(img, {left - 8, py(r.floor_ms)}, {left + 8, py(r.floor_ms)}, c, 2);
      }
    const int ly = top + 20 + 24 * static_cast<int>(s);
    cv::line(img, {W - right + 20, ly - 5}, {W - right + 50, ly - 5}, c, 3);
    cv::putText(img, series[s], {W - right + 60, ly}, font, 0.55, black, 1, cv::LINE_AA);
  }
  int ly = top + 40 + 24 * static_cast<int>(series.size());
  const cv::Scalar dark(60, 60, 60);
  const std::pair<MapOptions::Mode, const char*> keys[] = {{MapOptions::Mode::exact, "exact (error 0, at x = 0)"},
                                                           {MapOptions::Mode::grid, "grid (step 2..32)"},
                                                           {MapOptions::Mode::adaptive, "adaptive (tol.)"}};
  for (const auto& [kind, text] : keys) {
    marker(kind, {W - right + 35, ly - 5}, dark);
    cv::putText(img, text, {W - right + 60, ly}, font, 0.55, black, 1, cv::LINE_AA);
    ly += 24;
  }
  cv::line(img, {W - right + 27, ly - 5}, {W - right + 43, ly - 5}, dark, 2);
  cv::putText(img, "floor: 2 casts/pixel (at the y axis)", {W - right + 60, ly}, font, 0.45, black, 1, cv::LINE_AA);
  return img;
}

// Raw per-pixel arrays of a map, concatenated: status (uint8), skin_point
// (3 float64), face (int32), bary (2 float32), incidence_deg, contact_deg,
// transmittance (float32); native byte order. For comparing builds bit by bit.
void dump_map(const RefractionMap& m, const std::filesystem::path& path) {
  write_file_atomically(path, [&](std::ostream& out) {
    auto put = [&](const auto& v) {
      out.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof v[0]));
    };
    put(m.status), put(m.skin_point), put(m.face), put(m.bary), put(m.incidence_deg), put(m.contact_deg),
        put(m.transmittance);
  });
}

}  // namespace

// The CSV and the plot, both rendered before either is written.
void write_outputs(const std::vector<Row>& rows, int repeat, const std::string& csv_path, const std::string& plot_path) {
  const std::string csv = csv_text(rows, repeat);
  const cv::Mat img = plot_path.empty() ? cv::Mat() : plot(rows);
  if (!csv_path.empty()) {
    write_file_atomically(csv_path, csv);
    std::cout << "wrote " << csv_path << "\n";
  }
  if (!plot_path.empty()) {
    write_path_atomically(plot_path, [&](const std::filesystem::path& tmp) {
      if (!cv::imwrite(tmp.string(), img)) throw std::runtime_error("cv::imwrite failed");
    });
    std::cout << "wrote " << plot_path << "\n";
  }
}

Run add_bench_map(CLI::App& app) {
  struct Opts {
    std::string sizes = "640x480,1920x1080", shapes = join(bench::shape_names()),
                modes = "exact,grid:2,grid:8,grid:32,adaptive:0.1,adaptive:1,adaptive:10", csv, plot, dump;
    std::string chart = "auto";
    int repeat = 3;
    bool fresh_memory = false, exact_reasons = false;
    std::string export_dir;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand(
      "map", "Refraction map modes on the analytic parts: time, error against the exact trace, ratio to the ray-cast floor");
  sub->add_option("--sizes", o->sizes, "Image sizes WxH, comma separated (3840x2160 needs ~4 GB)")->capture_default_str();
  sub->add_option("--shapes", o->shapes,
                  "Parts: slab, band, dome, cap, bumps, and the random freeform parts field:SEED[:N], shell:SEED[:N] "
                  "(N quads per edge, default 160: 103k triangles; 224: 202k)")
      ->capture_default_str();
  sub->add_option("--modes", o->modes, "exact, grid:STEP, adaptive:TOLERANCE_UM")->capture_default_str();
  sub->add_option("--csv", o->csv, "Write the results as CSV (header row)");
  sub->add_option("--plot", o->plot, "Write a PNG plot of time against p99 error");
  sub->add_option("--dump", o->dump,
                 "Write each case's map as raw arrays to DIR/SHAPE_SIZE_MODE.bin (status u8, skin_point 3 f64, face "
                 "i32, bary 2 f32, incidence, contact, transmittance f32) to compare builds");
  sub->add_option("--chart", o->chart,
                  "auto: grid/adaptive interpolate the contact chart's coordinates, as clearfit map does by default; "
                  "none: they interpolate the 3D skin points (map.chart: none)")
      ->check(CLI::IsMember({"auto", "none"}))
      ->capture_default_str();
  sub->add_option("--repeat", o->repeat, "Timed runs per case; the best is reported")->check(CLI::Range(1, 100))->capture_default_str();
  sub->add_flag("--exact-reasons", o->exact_reasons,
                "Grid/adaptive maps resolve boundaries between two invalid reasons too (MapOptions::exact_reasons)");
  sub->add_option("--export", o->export_dir,
                  "Write each part as DIR/SHAPE.obj (contact group 'contact') and each camera with the part's pose as "
                  "DIR/SHAPE_WxH.cameramodel, and print the `clearfit map` command that maps them (whole-process timing)");
  sub->add_flag("--fresh-memory", o->fresh_memory,
                "Let freed memory go back to the OS (glibc default): every map then pays for first touches of its "
                "arrays, ~6 ms/MB on some VMs");

  return [o]() {
    const std::vector<Size> sizes = parse_sizes(o->sizes);
    const std::vector<ModeSpec> modes = parse_modes(o->modes);
    const std::vector<std::string> shapes = split(o->shapes);
    for (const std::string& s : shapes)
      if (!bench::known_shape(s))
        throw InputError("", "--shapes '" + s + "'", "is not a benchmark part",
                         "slab, band, dome, cap, bumps, field:SEED[:N], shell:SEED[:N]");
    if (shapes.empty()) throw InputError("", "--shapes", "is empty", "e.g. band,dome");
    if (!o->plot.empty() && std::filesystem::path(o->plot).extension() != ".png")
      throw InputError(o->plot, "--plot", "must name a .png file", "e.g. --plot bench.png");

    if (!o->fresh_memory) {  // keep freed memory for the next map (see --fresh-memory)
      mallopt(M_MMAP_THRESHOLD, 1 << 30);
      mallopt(M_TRIM_THRESHOLD, -1);
    }
    std::vector<Row> rows;
    const std::size_t cases = shapes.size() * sizes.size() * modes.size();
    std::size_t done = 0;
    for (const std::string& shape : shapes) {
      const auto scene = bench::make_scene(shape, o->chart == "auto");
      std::cerr << "bench: " << shape << ": " << scene->mesh.num_faces() << " triangles, mesh + index "
                << static_cast<int>(scene->build_ms) << " ms, chart " << static_cast<int>(scene->chart_ms) << " ms\n";
      for (const Size& size : sizes) {
        const CameraModel camera = bench::make_camera(size.w, size.h);
        const Rigid3 pose = bench::frame_part(scene->mesh, camera);
        if (!o->export_dir.empty()) export_part(o->export_dir, *scene, camera, pose, size.label());
        MapOptions exact_opt;
        const RefractionMap exact = compute_refraction_map(scene->trace(), camera, pose, exact_opt);
        const RayGrid rays = unproject_image(camera, 1);
        const bench::Floor fl = bench::measure_floor(*scene, rays, pose, exact, exact_opt.indices, o->repeat + 1);
        const bench::EmbreeFloor emb =
            bench::measure_embree_floor(scene->mesh, camera, rays, pose, exact, exact_opt.indices, o->repeat + 1);
        std::cerr << "bench: " << shape << " " << size.label() << ": floor " << fl.ms << " ms (" << fl.rays1 << " + "
                  << fl.rays2 << " rays), Embree floor BVH " << emb.build_ms << " + casts " << emb.cast_ms << " ms ("
                  << emb.rays1 << " + " << emb.rays2 << " rays, " << emb.outline_rays << " of the first the outline's), coverage " << 100 * exact.stats.coverage << " %\n";
        double exact_ms = 0, exact_cpu_ms = 0;
        const std::size_t first_row = rows.size();
        for (const ModeSpec& m : modes) {
          MapOptions opt;
          opt.mode = m.mode;
          opt.grid_step = m.step;
          opt.tolerance_um = m.tol_um;
          opt.exact_reasons = o->exact_reasons;
          RefractionMap best;
          double best_cpu = 1e300;
          for (int r = 0; r < o->repeat; ++r) {
            const double c0 = bench::process_cpu_ms();
            RefractionMap map = compute_refraction_map(scene->trace(), camera, pose, opt);
            best_cpu = std::min(best_cpu, bench::process_cpu_ms() - c0);
            if (r == 0 || map.stats.total_ms < best.stats.total_ms) best = std::move(map);
          }
          if (!o->dump.empty()) {
            std::filesystem::create_directories(o->dump);
            std::string name = shape + "_" + size.label() + "_" + m.label + ".bin";
            std::replace(name.begin(), name.end(), ':', '-');
            dump_map(best, std::filesystem::path(o->dump) / name);
          }
          Row row;
          row.shape = shape;
          row.size = size.label();
          row.mode = m.label;
          row.triangles = scene->mesh.num_faces();
          row.kind = m.mode;
          row.param = m.mode == MapOptions::Mode::grid ? m.step : m.mode == MapOptions::Mode::adaptive ? m.tol_um : 0;
          row.ms = best.stats.total_ms;
          row.trace_ms = best.stats.trace_ms;
          row.floor_ms = fl.ms;
          row.floor_recast_ms = fl.recast_ms;
          row.emb_ms = emb.cast_ms;
          row.emb_build_ms = emb.build_ms;
          row.emb_cpu_ms = emb.cpu_ms;
          row.index_ms = scene->index_ms;
          row.cpu_ms = best_cpu;
          row.floor_cpu_ms = fl.cpu_ms;
          row.first_ms = exact.stats.total_ms;
          row.unproject_ms = exact.stats.unproject_ms;
          row.traced = best.stats.traced;
          row.interpolated = best.stats.interpolated;
          row.valid = best.stats.by_status[0];
          row.pixels = best.stats.pixels;
          row.coverage = best.stats.coverage;
          row.est_max_um = best.stats.max_error_um;
          row.err = bench::compare_maps(best, exact);
          if (m.mode == MapOptions::Mode::exact) exact_ms = row.ms, exact_cpu_ms = row.cpu_ms;
          rows.push_back(row);
          std::cerr << "bench: [" << ++done << "/" << cases << "] " << shape << " " << size.label() << " " << m.label
                    << ": " << row.ms << " ms, p99 " << row.err.p99_um << " um\n";
        }
        if (exact_ms == 0) {  // exact not asked for: time the reference once more
          RefractionMap again = compute_refraction_map(scene->trace(), camera, pose, exact_opt);
          exact_ms = std::min(exact.stats.total_ms, again.stats.total_ms);
        }
        for (std::size_t k = first_row; k < rows.size(); ++k) rows[k].exact_ms = exact_ms, rows[k].exact_cpu_ms = exact_cpu_ms;
      }
    }
    print_legend(o->repeat, o->fresh_memory, o->chart);
    print_table(rows);
    write_outputs(rows, o->repeat, o->csv, o->plot);
    return 0;
  };
}

static const Registration registered{"map", 10, add_bench_map};

}  // namespace clearfit::cli
