// The scene file: its sections' keys (bind), their rules (validate), and the
// one place the file is read (read_scene). See the comment in scene.hpp.
#include <clearfit/cli/scene.hpp>

#include <clearfit/error.hpp>
#include <clearfit/yaml_key.hpp>
#include <clearfit/utf8.hpp>
#include <clearfit/geometry/import.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

namespace clearfit::cli {

// ---- SceneReader -----------------------------------------------------------

void SceneReader::fail(const YAML::Node& node, const std::string& key, const std::string& problem) const {
  const std::string where = (node.Mark().line >= 0 ? "line " + std::to_string(node.Mark().line + 1) + ", " : "") + "key '" + key + "'";
  throw InputError(file_.string(), where, problem, "see the scene file format in README.md");
}

void SceneReader::only_keys(const YAML::Node& map, const std::string& prefix, const std::set<std::string>& allowed) const {
  if (!map.IsMap()) fail(map, prefix, "expected a mapping of keys to values");
  for (const auto& kv : map) {
    const auto key = yaml_key(kv.first, file_.string());
    if (!allowed.count(key)) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      fail(kv.first, prefix.empty() ? key : prefix + "." + key, "unknown key (expected one of: " + list + ")");
    }
  }
}

// yaml-cpp keeps the first of two equal keys and drops the second without a word.
void SceneReader::no_duplicate_keys(const YAML::Node& node, const std::string& prefix) const {
  if (node.IsSequence())
    for (std::size_t i = 0; i < node.size(); ++i) no_duplicate_keys(node[i], prefix + "[" + std::to_string(i) + "]");
  if (!node.IsMap()) return;
  std::set<std::string> seen;
  for (const auto& kv : node) {
    const std::string key = yaml_key(kv.first, file_.string());
    const std::string full = prefix.empty() ? key : prefix + "." + key;
    if (!seen.insert(key).second) fail(kv.first, full, "is given twice; keep one");
    no_duplicate_keys(kv.second, full);
  }
}

std::optional<std::string> SceneReader::path(const YAML::Node& map, const std::string& key, const std::string& full) const {
  auto s = get<std::string>(map, key, full, "a file path");
  if (!s) return s;
  std::filesystem::path p(*s);
  return (p.is_absolute() ? p : file_.parent_path() / p).lexically_normal().string();
}

std::vector<double> SceneReader::numbers(const YAML::Node& n, const std::string& full, std::size_t count) const {
  if (!n.IsSequence() || (count && n.size() != count) || n.size() == 0)
    fail(n, full, count ? "expected a list of " + std::to_string(count) + " numbers" : "expected a list of numbers");
  std::vector<double> v;
  for (const auto& e : n) {
    try {
      v.push_back(e.as<double>());
    } catch (const YAML::Exception&) {
      fail(e, full, "expected a number, got '" + (e.IsScalar() ? e.Scalar() : std::string("a list or map")) + "'");
    }
    if (!std::isfinite(v.back())) fail(e, full, "expected a finite number");
  }
  return v;
}

// ---- SceneFields -----------------------------------------------------------

SceneFields::SceneFields(CLI::App& app, Options& options, std::vector<std::string> show)
    : app_(&app), writable_(&options), options_(&options), show_(std::move(show)) {}

SceneFields::SceneFields(const YAML::Node& node, const SceneReader& reader, const Options& options, std::string prefix)
    : options_(&options), node_(node), reader_(&reader), prefix_(std::move(prefix)) {}

bool SceneFields::shown(const std::string& k) const {
  for (const std::string& s : show_)
    if (s.empty() ? k.find('.') == std::string::npos : k == s || k.rfind(s + ".", 0) == 0) return true;
  return false;
}

bool SceneFields::given(const std::string& k) const {
  const auto it = options_->find(k);
  return it != options_->end() && it->second->count() > 0;
}

std::optional<YAML::Node> SceneFields::take(const std::string& name) {
  named_.insert(name);
  const YAML::Node n = node_[name];
  if (!n || given(full(name)) || ignored_.count(name)) return std::nullopt;
  reader_->note_given(full(name), n);
  return n;
}

void SceneFields::path(const std::string& name, std::string& value, const char* option, const std::string& help) {
  const std::string k = full(name);
  if (reading()) {
    if (take(name)) value = *reader_->path(node_, name, k);
  } else if (option && shown(k)) {
    registered(k, app_->add_option(option, value, help));
  }
}

void SceneFields::numbers(const std::string& name, std::vector<double>& value, std::size_t count, const char* option,
                          const std::string& help) {
  const std::string k = full(name);
  if (reading()) {
    if (const auto n = take(name)) value = reader_->numbers(*n, k, count);
  } else if (option && shown(k)) {
    CLI::Option* o = app_->add_option(option, value, help)->delimiter(',');
    if (count) o->expected(static_cast<int>(count));
    else o->capture_default_str();
    registered(k, o);
  }
}

void SceneFields::alternatives(const std::vector<std::string>& names) {
  if (reading()) {
    for (const auto& n : names)
      if (given(full(n))) ignored_.insert(names.begin(), names.end());
    return;
  }
  for (const auto& a : names)
    for (const auto& b : names)
      if (a < b && writable_->count(full(a)) && writable_->count(full(b))) (*writable_)[full(a)]->excludes((*writable_)[full(b)]);
}

void SceneFields::custom(const std::string& name,
                         const std::function<void(const YAML::Node&, const SceneReader&, const std::string&)>& read) {
  if (!reading()) return;
  named_.insert(name);
  if (const YAML::Node n = node_[name]) read(n, *reader_, full(name));
}

void SceneFields::finish() const { reader_->only_keys(node_, prefix_, named_); }

// ---- the sections ----------------------------------------------------------

void ContactSection::bind(SceneFields& f) {
  f.key("group", group, "--contact-group", "Contact surface: a group or object name (OBJ g/o, 3MF, glTF)");
  f.path("faces", faces, "--contact-faces", "Contact surface: a file of 0-based face indices in file order");
  f.numbers("normal", normal, 3, "--contact-normal",
            "Contact surface: faces whose outward normal is within --contact-angle of x,y,z (part frame)");
  f.alternatives({"group", "faces", "normal"});
  f.key("angle_deg", angle_deg, "--contact-angle", "Cone half-angle for --contact-normal, degrees");
}

void ContactSection::validate() const {
  if (!(std::isfinite(angle_deg) && angle_deg > 0 && angle_deg <= 180))
    rule_broken("angle_deg", angle_deg, "a cone half-angle in (0, 180] degrees");
}

void PartSection::bind(SceneFields& f) {
  f.path("mesh", mesh, "--mesh", "Part mesh (.stl .obj .ply .off .3mf .gltf .glb)");
  f.key("units", units, "--units", "Unit of the mesh file's numbers: um, mm, cm, m, in, ft (default: mm, or the file's own for 3MF/glTF)");
  f.path("camera", camera, "--camera", "Camera model (mrcal .cameramodel)");
  f.path("pose", pose, "--pose", "Pose file (clearfit.pose/1 JSON) with cam_from_part; default: the cameramodel's extrinsics");
  f.key("ior", indices.n_part, "--ior", "Index of refraction of the part");
  f.key("medium_ior", indices.n_medium, "--medium-ior", "Index of the camera-side medium (air 1.0, water 1.333, oil ~1.5)");
  f.key("skin_ior", indices.n_skin, "--skin-ior", "Index beyond the contact surface (skin)");
  f.section("contact", contact);
}

void PartSection::validate() const {
  if (!units.empty() && !parse_length_unit(units)) rule_broken("units", units, "one of um, mm, cm, m, in, ft");
  for (auto [key, value] : {std::pair{"ior", indices.n_part}, {"medium_ior", indices.n_medium}, {"skin_ior", indices.n_skin}})
    if (!(std::isfinite(value) && value >= 1.0 && value <= 3.0))
      rule_broken(key, value, "an index of refraction from 1 to 3 (air 1.0, water 1.333, acrylic 1.49, clear resins 1.49-1.55; "
                              "an index equal to the medium's is valid)");
  try {
    contact.validate();
  } catch (const SceneRuleError& e) {
    throw SceneRuleError("contact." + e.key, e.what());
  }
}

void MapSection::bind(SceneFields& f) {
  using N = MapOptions::Normals;
  using M = MapOptions::Mode;
  f.choice("normals", options.normals, {{"smooth", N::smooth}, {"flat", N::flat}}, "--normals", "Shading normals at the surfaces");
  f.choice("mode", options.mode, {{"exact", M::exact}, {"grid", M::grid}, {"adaptive", M::adaptive}}, "--mode",
           "exact: every pixel traced; grid: cells of --grid-step px interpolated; adaptive: cells refined until within --tolerance-um");
  f.key("grid_step", options.grid_step, "--grid-step", "Starting cell size for grid/adaptive, pixels (power of two, 2..256)");
  f.key("tolerance_um", options.tolerance_um, "--tolerance-um", "Adaptive: accepted interpolation error on the skin, micrometres");
  f.key("exact_reasons", options.exact_reasons, "--exact-reasons",
        "Grid/adaptive: resolve boundaries between two invalid reasons pixel by pixel too (default: validity "
        "boundaries only; elsewhere a pixel takes its nearest traced node's reason)");
  f.choice<std::string>("chart", chart, {{"auto", "auto"}, {"planar", "planar"}, {"lscm", "lscm"}, {"arap", "arap"}, {"none", "none"}},
                        "--chart", "Chart of the contact surface used for interpolation (none: interpolate in 3D)");
}

void MapSection::validate() const {
  const int s = options.grid_step;
  if (s < 2 || s > 256 || (s & (s - 1)) != 0) rule_broken("grid_step", s, "a power of two from 2 to 256");
  if (!(std::isfinite(options.tolerance_um) && options.tolerance_um > 0))
    rule_broken("tolerance_um", options.tolerance_um, "a positive number of micrometres");
}

void OutputsSection::bind(SceneFields& f) {
  f.path("map", map, "--out", "Output MAP.npy: float32 H x W x 3 skin points (part frame, mm), NaN where invalid");
  f.path("stats", stats, "--stats", "Output STATS.json: coverage, invalid pixels by reason, fast path, timings");
  f.path("inverse", inverse, "--inverse",
         "Output INV.npy: the inverse map for cv::remap, float32 T_h x T_w x 2 camera pixels per chart texel, NaN where invalid");
  f.path("folder", folder, "--out", "Output folder (default: the scene's outputs.folder, else out/ beside the scene)");
  f.key("texel_mm", texel_mm, "--texel-mm", "Texel size of the chart grid (the inverse map, the assessment), mm");
}

void OutputsSection::validate() const {
  if (!(std::isfinite(texel_mm) && texel_mm > 0)) rule_broken("texel_mm", texel_mm, "a positive length in mm");
}

void CapturesSection::bind(SceneFields& f) {
  f.path("baseline", baseline, "--baseline", "Not-worn capture: a video or a folder of images");
  f.path("worn", worn, "--worn", "Worn capture: a video or a folder of images");
  f.path("both", both, "--both", "One capture holding the baseline and then the press (split automatically)");
  f.key("window_frames", window_frames, "--window-frames", "Frames averaged per phase");
  f.key("max_motion_px", max_motion_px, "--max-motion-px", "Motion beyond this is refused, px");
  f.key("motion_compensation", motion_compensation, "--no-motion-compensation", "Do not measure or undo motion between frames");
  f.key("max_mb", max_mb, "--captures-max-mb", "Memory for a capture's partial sums, MB (one video beyond it is read again for its windows)");
}

void CapturesSection::validate() const {
  if (window_frames < 1) rule_broken("window_frames", window_frames, "at least 1 frame");
  if (!(std::isfinite(max_motion_px) && max_motion_px > 0)) rule_broken("max_motion_px", max_motion_px, "a positive number of pixels");
  if (!(std::isfinite(max_mb) && max_mb >= 1 && max_mb <= 1048576)) rule_broken("max_mb", max_mb, "a number of MB in 1..1048576");
  if (!both.empty() && (!baseline.empty() || !worn.empty()))
    throw SceneRuleError("both", "give either 'both' or 'baseline' and 'worn', not all three");
}

void BaselineSection::bind(SceneFields& f) {
  f.choice("part", part, {{"held", BaselinePart::held}, {"absent", BaselinePart::absent}, {"touching", BaselinePart::touching}},
           "--baseline-part",
           "How the not-worn capture was filmed: held (the part just off the skin), absent (no part) or touching (as when worn)");
  f.key("gap_mm", gap_mm, "--baseline-gap-mm",
        "Held or absent: the skin's distance beyond the contact surface in the not-worn capture, mm, or auto (estimated)");
  f.key("max_shift_px", search.max_shift_px, "--baseline-max-shift-px",
        "Held or absent: the largest move of the skin texture between the phases' first frames (camera or skin) measured with "
        "the gap, px (0: not measured)");
  f.key("gap_sigma_in_signal", search.sigma_in_signal, "--no-baseline-gap-sigma",
        "Held or absent, gap auto: do not carry the estimated gap's sigma into each texel's signal sigma and detection gate");
}

std::optional<double> BaselineSection::gap() const {
  if (gap_mm == "auto") return std::nullopt;
  return std::stod(gap_mm);
}

void BaselineSection::validate() const {
  validate_options(search);
  if (gap_mm == "auto") return;
  std::size_t used = 0;
  double g = NAN;
  try {
    g = std::stod(gap_mm, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != gap_mm.size() || !std::isfinite(g)) rule_broken("gap_mm", "'" + gap_mm + "'", "auto or a length in mm");
  if (g < 0 || g > 20)
    rule_broken("gap_mm", gap_mm, "a length from 0 to 20 mm (the skin's distance beyond the part's contact surface), or auto");
  if (part == BaselinePart::touching && g != 0)
    throw SceneRuleError("gap_mm", "must be auto or 0 with part: touching (the skin touches the part), got " + gap_mm);
}

void CalibrationSection::bind(SceneFields& f) {
  f.path("pressure", pressure, "--calibration", "Per-person pressure calibration (from clearfit calibrate-pressure)");
  f.key("person", person, "--person", "Who wears the part (checked against the calibration)");
}

void GlareSection::bind(SceneFields& f) {
  f.key("enabled", options.enabled, "--no-glare-mask", "Do not mask specular highlights (glare) out of the signal");
  f.key("margin_px", options.margin_px, "--glare-margin-px", "Glare regions grow by this many pixels");
  f.key("tail_light", options.tail_light, "--glare-tail-light",
        "... or out to where a highlight's light, measured around it, is below this share of the skin's green (0: the margin only)");
  f.key("threshold_sigmas", options.threshold_sigmas);
  f.key("min_change", options.min_change);
  f.key("min_static", options.min_static);
  f.key("outline_band_px", options.outline_band_px);
  f.key("max_fraction", options.max_fraction);
}

void GlareSection::validate() const {
  validate_options(options);
}

void PhaseRegistrationSection::bind(SceneFields& f) {
  f.key("enabled", options.enabled, "--no-phase-registration",
        "Do not register the worn capture's skin to the not-worn one's on the chart (skin that slid or bulged is then read as pressure)");
  f.key("highpass_mm", options.highpass_mm);
  f.key("smoothing_mm", options.smoothing_mm, "--phase-registration-smoothing-mm", "Smoothing of the phases' displacement field, mm");
  f.key("red_green_ratio", options.red_green_ratio);
  f.key("max_displacement_mm", options.max_displacement_mm);
  f.key("min_match", options.min_match);
  f.key("max_weak_fraction", options.max_weak_fraction);
}

void PhaseRegistrationSection::validate() const {
  validate_options(options);
}

void OutlineSection::bind(SceneFields& f) {
  f.key("enabled", options.enabled, "--no-outline",
        "Do not place the worn capture by the contact surface's outline (a move of the camera between the phases' first "
        "frames is then followed as if the skin had slid)");
  f.key("band_px", options.band_px);
  f.key("smoothing_px", options.smoothing_px);
  f.key("max_sigma_px", options.max_sigma_px);
  f.key("min_contrast", options.min_contrast);
  f.key("max_shift_px", options.max_shift_px);
}

void OutlineSection::validate() const {
  validate_options(options);
}

void VignettingSection::bind(SceneFields& f) {
  f.key("enabled", options.enabled, "--no-vignetting",
        "Do not estimate the image's fall-off when the phases see the skin at different pixels (a held or absent baseline)");
  f.key("max_abs", options.max_abs);
  f.key("min_spread", options.min_spread);
  f.key("stride_px", options.stride_px);
  f.key("pressed_margin_mm", options.pressed_margin_mm);
}

void VignettingSection::validate() const {
  validate_options(options);
}

void TimeSeriesSection::bind(SceneFields& f) {
  f.key("enabled", options.enabled, "--no-timeseries", "Do not follow the worn phase over time (no timeline)");
  f.key("cell_px", options.cell_px, "--timeseries-cell-px", "Cell edge of the time series in the camera image, px");
  f.key("max_mb", options.max_mb, "--timeseries-max-mb", "Memory for the time series, MB (the time step doubles beyond it)");
  f.key("texel_mm", options.texel_mm);
  f.key("onset_window_s", options.onset_window_s);
  f.key("min_refill_taus", options.min_refill_taus);
}

void TimeSeriesSection::validate() const {
  validate_options(options);
}

void AssessSection::bind(SceneFields& f) {
  f.section("glare", glare);
  f.section("phase_registration", phase_registration);
  f.section("outline", outline);
  f.section("vignetting", vignetting);
  f.section("timeseries", timeseries);
  f.key("normalise_exposure", normalise_exposure, "--no-exposure-normalisation",
        "Do not divide each 5-frame chunk by its exposure / white-balance / flicker gain");
  f.key("smoothing_mm", smoothing_mm, "--smoothing-mm", "Gaussian smoothing of the signal on the chart, mm");
  f.key("skin_blur_mm", skin_blur_mm, "--skin-blur-mm",
        "The skin's lateral blur of the pressure (Gaussian sigma, mm): the signal reads the pressure blurred by it, a resolution "
        "error undone to first order and part of each texel's sigma (default: the blur the pressure calibration was fitted with, "
        "else 0.3; a blur given that differs from the calibration's is warned about)");
  f.key("curvature_smoothing_mm", curvature_smoothing_mm);
  f.numbers("thresholds_kpa", thresholds_kpa, 0, "--thresholds-kpa", "Hotspot thresholds, kPa (needs a pressure calibration)");
  f.numbers("signal_thresholds", signal_thresholds, 0, "--signal-threshold",
            "Without a calibration: hotspot thresholds on the blanching signal y = ln(G/G0) (default: --significance-sigmas times the noise)");
  f.key("significance_sigmas", significance_sigmas, "--significance-sigmas",
        "Without a calibration and --signal-threshold: significant blanching is this many noise sigmas above the reference");
  f.key("lossy_outline_px", lossy_outline_px, "--lossy-outline-px",
        "Lossy (H.264) captures: the seen skin within this many camera pixels of its outline is left unseen (0: off)");
  f.key("hysteresis_sigmas", hysteresis_sigmas, "--hysteresis-sigmas",
        "With a calibration: a texel below detection but connected to a detected one keeps its pressure where its signal "
        "is at least this many of its sigmas (the places' tails; at the detection gate or above: off)");
  f.numbers("reference_uv_mm", reference_uv_mm, 2, "--reference-uv-mm",
            "Centre u,v (chart mm) of an unpressed reference disk (default: automatic)");
  f.key("reference_radius_mm", reference_radius_mm, "--reference-radius-mm", "Radius of the reference disk, mm");
  f.key("min_hotspot_area_mm2", min_hotspot_area_mm2, "--min-hotspot-area-mm2", "Smaller hotspots are dropped, mm²");
}

void AssessSection::validate() const {
  try {
    glare.validate();
  } catch (const SceneRuleError& e) {
    throw SceneRuleError("glare", e.what());
  }
  try {
    timeseries.validate();
  } catch (const SceneRuleError& e) {
    throw SceneRuleError("timeseries", e.what());
  }
  try {
    phase_registration.validate();
  } catch (const SceneRuleError& e) {
    throw SceneRuleError("phase_registration", e.what());
  }
  try {
    outline.validate();
  } catch (const SceneRuleError& e) {
    throw SceneRuleError("outline", e.what());
  }
  try {
    vignetting.validate();
  } catch (const SceneRuleError& e) {
    throw SceneRuleError("vignetting", e.what());
  }
  // The signal's keys, each checked alone by BlanchingOptions::validate (their one home) so that the error names its key.
  for (const auto& [key, value] : {std::pair{"smoothing_mm", &BlanchingOptions::smoothing_mm}, {"skin_blur_mm", &BlanchingOptions::skin_blur_mm},
                                   {"curvature_smoothing_mm", &BlanchingOptions::curvature_smoothing_mm},
                                   {"reference_radius_mm", &BlanchingOptions::reference_radius_mm}}) {
    BlanchingOptions one;
    one.*value = blanching().*value;
    try {
      one.validate();
    } catch (const std::invalid_argument& e) {
      throw SceneRuleError(key, e.what());
    }
  }
  for (double t : thresholds_kpa)
    if (!(std::isfinite(t) && t > 0)) rule_broken("thresholds_kpa", t, "positive pressures in kPa");
  for (double t : signal_thresholds)
    if (!(std::isfinite(t) && t > 0 && t < 5)) rule_broken("signal_thresholds", t, "positive values of the signal ln(G/G0) below 5");
  if (!(std::isfinite(significance_sigmas) && significance_sigmas >= 1 && significance_sigmas <= 100))
    rule_broken("significance_sigmas", significance_sigmas, "a number of noise sigmas in [1, 100]");
  if (!(std::isfinite(hysteresis_sigmas) && hysteresis_sigmas >= 1 && hysteresis_sigmas <= 100))
    rule_broken("hysteresis_sigmas", hysteresis_sigmas, "a number of noise sigmas in [1, 100]");
  if (!(std::isfinite(lossy_outline_px) && lossy_outline_px >= 0 && lossy_outline_px <= 100))
    rule_broken("lossy_outline_px", lossy_outline_px, "camera pixels in [0, 100] (0: off)");
  if (!(std::isfinite(min_hotspot_area_mm2) && min_hotspot_area_mm2 > 0))
    rule_broken("min_hotspot_area_mm2", min_hotspot_area_mm2, "a positive area in mm²");
}

BlanchingOptions AssessSection::blanching() const {
  BlanchingOptions o;
  o.smoothing_mm = smoothing_mm;
  o.skin_blur_mm = skin_blur_mm;
  o.curvature_smoothing_mm = curvature_smoothing_mm;
  if (reference_uv_mm.size() == 2) o.reference_uv_mm = Vec2(reference_uv_mm[0], reference_uv_mm[1]);
  o.reference_radius_mm = reference_radius_mm;
  return o;
}

// ---- the whole file --------------------------------------------------------

void Scene::bind(SceneFields& f) {
  part.bind(f);
  f.section("map", map);
  f.section("outputs", outputs);
  f.section("captures", captures);
  f.section("baseline", baseline);
  f.section("calibration", calibration);
  f.section("assess", assess);
  f.custom("simulation", [this](const YAML::Node& n, const SceneReader& r, const std::string&) {
    simulation.emplace();
    simulation->read(n, r);
  });
}

void Scene::validate() const {
  auto check = [](const char* section, const auto& s) {
    try {
      s.validate();
    } catch (const SceneRuleError& e) {
      throw SceneRuleError(*section && !e.key.empty() ? std::string(section) + "." + e.key : *section ? section : e.key, e.what());
    }
  };
  check("", part);
  check("map", map);
  check("outputs", outputs);
  check("captures", captures);
  check("baseline", baseline);
  check("calibration", calibration);
  check("assess", assess);
  if (simulation) check("simulation", *simulation);
}

SceneFields::Options add_scene_options(CLI::App& sub, Scene& scene, const std::vector<std::string>& show) {
  SceneFields::Options options;
  SceneFields f(sub, options, show);
  scene.bind(f);
  return options;
}

void read_scene(const std::filesystem::path& file, Scene& scene, const SceneFields::Options& options) {
  if (std::filesystem::is_directory(file)) throw InputError(file.string(), "", "is a directory, expected a scene file (YAML)");
  if (!std::filesystem::exists(file)) throw InputError(file.string(), "", "scene file not found");
  std::ifstream in(file, std::ios::binary);
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (!in) throw InputError(file.string(), "", "cannot read the scene file", "check its permissions");
  const std::string text = buffer.str();
  if (const auto bad = first_invalid_utf8(text); bad != std::string::npos)
    throw InputError(file.string(), "line " + std::to_string(1 + std::count(text.begin(), text.begin() + static_cast<long>(bad), '\n')),
                     "is not UTF-8 text", "save the scene file as UTF-8");
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw InputError(file.string(), "line " + std::to_string(e.mark.line + 1) + ", column " + std::to_string(e.mark.column + 1),
                     "not valid YAML: " + e.msg);
  } catch (const YAML::Exception& e) {
    throw InputError(file.string(), "", std::string("cannot read the scene file: ") + e.what());
  }
  if (!root || root.IsNull()) throw InputError(file.string(), "", "is empty", "see the scene file format in README.md");
  const SceneReader reader(file);
  if (!root.IsMap()) reader.fail(root, "", "expected a mapping of keys to values");
  reader.no_duplicate_keys(root, "");
  scene.file = file;
  SceneFields f(root, reader, options);
  scene.bind(f);
  f.finish();
  scene.file_keys = reader.given();
  check_scene(scene, options);
}

void check_scene(const Scene& scene, const SceneFields::Options& options) {
  try {
    scene.validate();
  } catch (const SceneRuleError& e) {
    const auto it = options.find(e.key);
    if (it != options.end() && (it->second->count() > 0 || scene.file.empty()))
      throw InputError("", it->second->get_name(), e.what());
    if (!scene.file.empty()) throw InputError(scene.file.string(), "key '" + e.key + "'", e.what(), "see the scene file format in README.md");
    throw InputError("", e.key, e.what());
  }
}

bool given_on_command_line(const SceneFields::Options& options, const std::string& key) {
  const auto it = options.find(key);
  return it != options.end() && it->second->count() > 0;
}

}  // namespace clearfit::cli
