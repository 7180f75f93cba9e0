#pragma once
// The scene file (YAML): everything a run needs, named once. Paths in it are
// relative to the file. Unknown keys and wrong types are errors naming the key
// and the line; values breaking a rule name the key (or the option), the value
// and the rule.
//
//   mesh: wristband.obj          # part mesh
//   units: mm                    # of the mesh file's numbers (STL/OBJ/PLY/OFF)
//   ior: 1.49                    # part
//   medium_ior: 1.0              # camera side
//   skin_ior: 1.4
//   contact: {group: contact}    # or {faces: faces.txt} or {normal: [0, 0, -1], angle_deg: 30}
//   camera: camera.cameramodel
//   pose: pose.json              # optional; default: the cameramodel's extrinsics
//   map: {normals: smooth, mode: adaptive, grid_step: 16, tolerance_um: 1.0, chart: auto, exact_reasons: false}
//   outputs: {map: out/map.npy, stats: out/map-stats.json, inverse: out/inverse.npy, texel_mm: 0.05,
//             folder: out}
//   baseline: {part: held, gap_mm: auto}   # how the not-worn capture was filmed (held | absent | touching)
//   captures: {baseline: a.mkv, worn: b.mkv, both: c.mkv, window_frames: 100, max_motion_px: 10,
//              motion_compensation: true, max_mb: 1024}
//   calibration: {pressure: calibration.json, person: P1}
//   assess: {smoothing_mm: 0.25, thresholds_kpa: [4.3, 5.5], reference_uv_mm: [u, v],
//            reference_radius_mm: 2, min_hotspot_area_mm2: 0.05,
//            signal_thresholds: [0.01], significance_sigmas: 5}   # the last two without a calibration
//   simulation: {...}            # clearfit simulate (README.md; read in cli/scene_simulation.cpp)
//
// ONE HOME PER PARAMETER. How it works, and how to add to it:
//  - Each section of the file is one struct below (PartSection holds the
//    top-level keys). A field's default is written once: in the module's own
//    options struct when the module has one (the section embeds it, e.g.
//    MapSection::options is a MapOptions, or initialises from it, e.g.
//    `= AssessmentOptions{}.window_frames`), else here.
//  - The section's `bind(SceneFields&)` names each key once, with its
//    command-line option (or nullptr) and help text. That one line both reads
//    the key from the file and registers the option, so the two cannot drift.
//  - The section's `validate()` checks the rules (Ceres' Options style) and
//    throws SceneRuleError(key, message naming the value and the rule); the
//    error the user sees names the option when the value came from the command
//    line, else the scene file and key.
//  - The file is read in one place, read_scene(); the command line overrides
//    through the same bindings (a key whose option was given keeps the command
//    line's value). Commands hand the checked values down as plain module
//    options.
//  To add a key: a field (with its default) in its section, one line in its
//  bind(), its rule in validate(). To add a section: a struct with bind() and
//  validate(), a member of Scene, one line in Scene::bind() and Scene::validate().
//  Commands pick the options they show with add_scene_options(sub, scene, {"map", "outputs.map"}).
#include <clearfit/error.hpp>
#include <clearfit/fit/assessment.hpp>
#include <clearfit/fit/simulate.hpp>
#include <clearfit/fit/simulate_photometric.hpp>
#include <clearfit/refraction/baseline_map.hpp>
#include <clearfit/refraction/map.hpp>
#include <CLI/CLI.hpp>
#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace clearfit::cli {

/// A value breaking a rule: `key` relative to the section that throws it.
struct SceneRuleError : std::runtime_error {
  SceneRuleError(std::string key, const std::string& message) : std::runtime_error(message), key(std::move(key)) {}
  std::string key;
};

/// "must be ...; got <value>" for rule messages.
template <class T>
[[noreturn]] void rule_broken(const std::string& key, const T& value, const std::string& rule) {
  std::ostringstream s;
  s << "must be " << rule << ", got " << value;
  throw SceneRuleError(key, s.str());
}

/// Runs each module options' own `validate()`; its error (std::invalid_argument or InputError, naming the
/// field) becomes a SceneRuleError of the section that holds them, so the scene's message names the file and line.
template <class... Options>
void validate_options(const Options&... options) {
  try {
    (options.validate(), ...);
  } catch (const std::invalid_argument& e) {
    throw SceneRuleError("", e.what());
  } catch (const InputError& e) {
    throw SceneRuleError("", e.what());
  }
}

/// Reads keys of one scene file with errors that name the file, line and key.
class SceneReader {
 public:
  explicit SceneReader(std::filesystem::path file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const YAML::Node& node, const std::string& key, const std::string& problem) const;
  void only_keys(const YAML::Node& map, const std::string& prefix, const std::set<std::string>& allowed) const;
  /// Throws (line, key) at the second of two equal keys anywhere under `node`.
  void no_duplicate_keys(const YAML::Node& node, const std::string& prefix) const;
  template <class T>
  std::optional<T> get(const YAML::Node& map, const std::string& key, const std::string& full, const char* what) const {
    const YAML::Node n = map[key];
    if (!n) return std::nullopt;
    if (!n.IsScalar()) fail(n, full, std::string("expected ") + what);
    try {
      return n.as<T>();
    } catch (const YAML::Exception&) {
      fail(n, full, std::string("expected ") + what + ", got '" + n.Scalar() + "'");
    }
  }
  /// A path, resolved against the scene file's folder.
  std::optional<std::string> path(const YAML::Node& map, const std::string& key, const std::string& full) const;
  /// A list of finite numbers (exactly `count` unless 0).
  std::vector<double> numbers(const YAML::Node& n, const std::string& full, std::size_t count) const;
  const std::filesystem::path& file() const { return file_; }
  /// Records that the file gives the key `full` (and the command line does not), at `node`'s line.
  void note_given(const std::string& full, const YAML::Node& node) const { given_[full] = node.Mark().line + 1; }
  /// The keys noted so far with their lines (1-based).
  const std::map<std::string, int>& given() const { return given_; }

 private:
  std::filesystem::path file_;
  mutable std::map<std::string, int> given_;
};

/// The keys of one section: reads them from the file, or registers their
/// command-line options (see the comment at the top).
class SceneFields {
 public:
  /// Registered options by full key ("map.mode"), kept from registration to reading.
  using Options = std::map<std::string, CLI::Option*>;
  /// Registering: adds the options of keys under one of `show` ("map",
  /// "outputs.map"; "" for the top-level keys) to `app`.
  SceneFields(CLI::App& app, Options& options, std::vector<std::string> show);
  /// Reading: `node` is the section; keys whose option was given are skipped.
  SceneFields(const YAML::Node& node, const SceneReader& reader, const Options& options, std::string prefix = {});

  bool reading() const { return reader_ != nullptr; }
  /// A number, whole number, text or true/false. A bool's option is a flag:
  /// "--exact-reasons" sets true, "--no-motion-compensation" (starting "--no-") sets false.
  template <class T>
  void key(const std::string& name, T& value, const char* option = nullptr, const std::string& help = {});
  /// A file path, resolved against the scene file's folder.
  void path(const std::string& name, std::string& value, const char* option = nullptr, const std::string& help = {});
  /// One of named values.
  template <class E>
  void choice(const std::string& name, E& value, const std::vector<std::pair<std::string, E>>& names, const char* option = nullptr,
              const std::string& help = {});
  /// A list of numbers, exactly `count` of them unless 0 (comma-separated on the command line).
  void numbers(const std::string& name, std::vector<double>& value, std::size_t count, const char* option = nullptr,
               const std::string& help = {});
  /// Keys that are alternatives (the contact surface by group, faces or normal):
  /// when the command line gives any of them, the file's are all ignored.
  void alternatives(const std::vector<std::string>& names);
  /// A nested section (`name: {...}`) read by `section.bind()`.
  template <class S>
  void section(const std::string& name, S& section);
  /// A key read by hand (lists of mappings, presets): `read` gets its node. No option.
  void custom(const std::string& name, const std::function<void(const YAML::Node&, const SceneReader&, const std::string& full)>& read);
  /// Reading: fails on keys of the section that no bind line named.
  void finish() const;

 private:
  std::string full(const std::string& name) const { return prefix_.empty() ? name : prefix_ + "." + name; }
  bool shown(const std::string& full) const;
  bool given(const std::string& full) const;  ///< its option was given on the command line
  /// Reading: the node of `name` if the file has it and the command line did not give it.
  std::optional<YAML::Node> take(const std::string& name);
  void registered(const std::string& full, CLI::Option* option) { (*writable_)[full] = option; }

  CLI::App* app_ = nullptr;
  Options* writable_ = nullptr;
  const Options* options_ = nullptr;
  std::vector<std::string> show_;
  YAML::Node node_;
  const SceneReader* reader_ = nullptr;
  std::string prefix_;
  std::set<std::string> named_, ignored_;
};

template <class T>
const char* scene_type_name() {
  if constexpr (std::is_same_v<T, bool>) return "true or false";
  else if constexpr (std::is_integral_v<T>) return "a whole number";
  else if constexpr (std::is_floating_point_v<T>) return "a number";
  else return "text";
}

template <class T>
void SceneFields::key(const std::string& name, T& value, const char* option, const std::string& help) {
  const std::string k = full(name);
  if (reading()) {
    if (const auto n = take(name)) value = *reader_->get<T>(node_, name, k, scene_type_name<T>());
  } else if (option && shown(k)) {
    if constexpr (std::is_same_v<T, bool>)
      registered(k, std::string(option).rfind("--no-", 0) == 0 ? app_->add_flag_callback(option, [&value] { value = false; }, help)
                                                              : app_->add_flag(option, value, help));
    else registered(k, app_->add_option(option, value, help)->capture_default_str());
  }
}

template <class E>
void SceneFields::choice(const std::string& name, E& value, const std::vector<std::pair<std::string, E>>& names, const char* option,
                         const std::string& help) {
  const std::string k = full(name);
  std::string list;
  for (const auto& [text, v] : names) list += (list.empty() ? "" : ", ") + text;
  if (reading()) {
    if (!take(name)) return;
    const std::string text = *reader_->get<std::string>(node_, name, k, list.c_str());
    for (const auto& [t, v] : names)
      if (t == text) return void(value = v);
    reader_->fail(node_[name], k, "'" + text + "' is not one of the allowed values (" + list + ")");
  } else if (option && shown(k)) {
    std::vector<std::string> texts;
    for (const auto& [text, v] : names) texts.push_back(text);
    CLI::Option* o = app_->add_option_function<std::string>(
                             option,
                             [&value, names](const std::string& text) {
                               for (const auto& [t, v] : names)
                                 if (t == text) value = v;
                             },
                             help)
                         ->check(CLI::IsMember(texts));
    for (const auto& [t, v] : names)
      if (v == value) o->default_str(t);
    registered(k, o);
  }
}

template <class S>
void SceneFields::section(const std::string& name, S& s) {
  const std::string k = full(name);
  named_.insert(name);
  if (!reading()) {
    SceneFields sub(*app_, *writable_, show_);
    sub.prefix_ = k;
    s.bind(sub);
    return;
  }
  const YAML::Node n = node_[name];
  if (!n) {
    // Absent from the file: only the command line's values (nothing to read).
    return;
  }
  if (!n.IsMap()) reader_->fail(n, k, "expected a mapping of keys to values");
  SceneFields sub(n, *reader_, *options_, k);
  s.bind(sub);
  sub.finish();
}

// ---- the sections ----------------------------------------------------------

/// `contact:`: the contact surface, by one of group, faces or normal (+ angle).
struct ContactSection {
  std::string group, faces;
  std::vector<double> normal;  ///< x, y, z in the part frame; empty: not given
  double angle_deg = 30.0;
  void bind(SceneFields& f);
  void validate() const;
};

/// The top-level keys: the part, its indices, the camera and its pose.
struct PartSection {
  std::string mesh, units, camera, pose;  ///< units empty: the file's own (mm for STL/OBJ/PLY/OFF)
  optics::Indices indices;                ///< ior, medium_ior, skin_ior (defaults: optics::Indices)
  ContactSection contact;
  void bind(SceneFields& f);
  void validate() const;
};

/// `map:`: how the refraction map is traced.
struct MapSection {
  MapOptions options;  ///< normals, mode, grid_step, tolerance_um, exact_reasons (the indices come from PartSection)
  std::string chart = "auto";  ///< auto, planar, lscm, arap or none
  void bind(SceneFields& f);
  void validate() const;
};

/// `outputs:`: where results go.
struct OutputsSection {
  std::string map, stats, inverse, folder;
  double texel_mm = 0.05;  ///< chart texel of the inverse map and the assessment grid
  void bind(SceneFields& f);
  void validate() const;
};

/// `captures:`: the not-worn and worn captures and how they are averaged.
struct CapturesSection {
  std::string baseline, worn, both;
  int window_frames = AssessmentOptions{}.window_frames;
  double max_motion_px = AssessmentOptions{}.max_motion_px;
  bool motion_compensation = AssessmentOptions{}.compensate_motion;
  double max_mb = AssessmentOptions{}.max_sums_mb;
  void bind(SceneFields& f);
  void validate() const;
};

/// `baseline:`: how the not-worn capture was filmed (refraction/baseline_map.hpp):
/// the part held off the skin by an air gap, absent, or touching as when worn;
/// the gap in mm or `auto` (estimated from the captures, fit/baseline_gap.hpp).
struct BaselineSection {
  BaselinePart part = BaselinePart::held;
  std::string gap_mm = "auto";
  GapSearchOptions search;  ///< the gap's search and the camera's move between the phases (max_shift_px)
  /// The gap given (mm), or nullopt for auto. Call after validate().
  std::optional<double> gap() const;
  void bind(SceneFields& f);
  void validate() const;
};

/// `calibration:`: the person's pressure calibration.
struct CalibrationSection {
  std::string pressure, person;
  void bind(SceneFields& f);
  void validate() const {}
};

/// `assess:`: the blanching signal and the hotspots.
/// `assess.glare:` the glare mask (fit/glare.hpp); its defaults and rules are GlareOptions'.
struct GlareSection {
  GlareOptions options;
  void bind(SceneFields& f);
  void validate() const;
};

/// `assess.phase_registration:` skin that slid or bulged between the phases
/// (fit/phase_registration.hpp); its defaults and rules are PhaseRegistrationOptions'.
struct PhaseRegistrationSection {
  PhaseRegistrationOptions options;
  void bind(SceneFields& f);
  void validate() const;
};

/// `assess.outline:` the camera's move between the phases from the contact surface's outline
/// (fit/outline.hpp); its defaults and rules are OutlineOptions'.
struct OutlineSection {
  OutlineOptions options;
  void bind(SceneFields& f);
  void validate() const;
};

/// `assess.vignetting:` the fall-off between phases seen at different pixels (a held or absent
/// baseline; fit/vignetting.hpp); its defaults and rules are VignettingOptions'.
struct VignettingSection {
  VignettingOptions options;
  void bind(SceneFields& f);
  void validate() const;
};

/// `assess.timeseries`: the worn phase over time (fit/timeseries.hpp).
struct TimeSeriesSection {
  TimeSeriesOptions options;
  void bind(SceneFields& f);
  void validate() const;
};

struct AssessSection {
  GlareSection glare;
  PhaseRegistrationSection phase_registration;
  OutlineSection outline;
  VignettingSection vignetting;
  TimeSeriesSection timeseries;
  bool normalise_exposure = AssessmentOptions{}.normalise_gains;  ///< per-chunk exposure / white-balance / flicker gains
  double smoothing_mm = BlanchingOptions{}.smoothing_mm;
  double skin_blur_mm = BlanchingOptions{}.skin_blur_mm;                      ///< the skin's lateral blur (fit/skin_blur.hpp)
  double curvature_smoothing_mm = BlanchingOptions{}.curvature_smoothing_mm;  ///< of the blur's first-order term
  std::vector<double> thresholds_kpa = AssessmentOptions{}.thresholds_kpa;
  std::vector<double> signal_thresholds;  ///< without a calibration: thresholds on the signal y; empty: significance_sigmas
  double significance_sigmas = AssessmentOptions{}.signal_threshold_sigmas;
  double hysteresis_sigmas = AssessmentOptions{}.hysteresis_sigmas;  ///< a detected place's tail, in its texels' σ
  double lossy_outline_px = AssessmentOptions{}.lossy_outline_px;    ///< lossy captures: the seen skin's outline left out, camera px
  std::vector<double> reference_uv_mm;  ///< empty: automatic
  double reference_radius_mm = BlanchingOptions{}.reference_radius_mm;
  double min_hotspot_area_mm2 = AssessmentOptions{}.min_hotspot_area_mm2;
  void bind(SceneFields& f);
  void validate() const;
  /// The signal's options these keys give (the others at their defaults); their rules are BlanchingOptions'.
  BlanchingOptions blanching() const;
};

/// `simulation:` (clearfit simulate). Read by hand in cli/scene_simulation.cpp
/// (lists of sources, presets): its ranges are checked as it is read, with the
/// line; the modules' validate() checks the combinations.
struct SimulationSection {
  std::string preset = "none";  ///< realistic: every real-capture effect at a plausible strength (cli/scene_simulation.cpp)
  std::uint64_t seed = 1;
  std::string out;
  sim::VideoFormat format = sim::VideoFormat::huffyuv;
  double scale = 1.0;
  sim::Timeline timeline;
  SkinParameters skin;
  sim::CameraSettings camera;
  sim::PressureFieldSpec field;
  std::optional<std::string> pressure_map;
  std::optional<sim::PressOptions> presses;
  sim::BaselineGeometry baseline;  ///< how the not-worn capture is rendered (default: held 1 mm off the skin)
  sim::PhotometricEffects photometric;  ///< glare, exposure steps and drifts, flicker drift (cli/simulate_photometric.cpp)
  sim::SkinMotion skin_motion;          ///< skin sliding and bulging between the phases (simulation.skin_motion)
  void read(const YAML::Node& node, const SceneReader& reader);
  void validate() const;
};

/// A whole scene file.
struct Scene {
  std::filesystem::path file;  ///< empty: no scene file (command line only)
  /// The keys the file gave and the command line did not ("assess.thresholds_kpa"), with their lines (1-based).
  std::map<std::string, int> file_keys;
  PartSection part;
  MapSection map;
  OutputsSection outputs;
  CapturesSection captures;
  BaselineSection baseline;
  CalibrationSection calibration;
  AssessSection assess;
  std::optional<SimulationSection> simulation;
  void bind(SceneFields& f);
  void validate() const;  ///< SceneRuleError with the full key
  /// The part's map options: MapSection::options with PartSection's indices.
  MapOptions map_options() const {
    MapOptions o = map.options;
    o.indices = part.indices;
    return o;
  }
};

/// Registers the command-line options of the keys under `show` ("" = the
/// top-level keys, "map", "outputs.map", ...), bound to `scene`'s fields.
/// Returns what read_scene/check_scene need to know which were given.
SceneFields::Options add_scene_options(CLI::App& sub, Scene& scene, const std::vector<std::string>& show);

/// Reads the scene file into `scene` (keys whose option was given keep the
/// command line's value; paths resolved against the file's folder), then
/// check_scene(). Throws InputError (file, "line N, key 'k'", what was expected).
void read_scene(const std::filesystem::path& file, Scene& scene, const SceneFields::Options& options);

/// Whether `key`'s option was given on the command line.
bool given_on_command_line(const SceneFields::Options& options, const std::string& key);

/// Scene::validate(), the error naming the option if the value came from the
/// command line, else the scene file and key.
void check_scene(const Scene& scene, const SceneFields::Options& options);

}  // namespace clearfit::cli
