#include <clearfit/error.hpp>
#include <clearfit/yaml_key.hpp>
#include <clearfit/study/manifest.hpp>

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <map>
#include <set>

namespace clearfit::study {
namespace {

namespace fs = std::filesystem;

/// Located reading of the manifest's YAML (file, line, key in every message).
class Reader {
 public:
  explicit Reader(fs::path file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const YAML::Node& node, const std::string& key, const std::string& problem) const {
    const auto line = node.Mark().line;
    throw InputError(file_.string(), (line >= 0 ? "line " + std::to_string(line + 1) + ", " : "") + "key '" + key + "'",
                     problem, "see the study manifest format in README.md");
  }
  void keys(const YAML::Node& map, const std::string& where, const std::set<std::string>& allowed) const {
    if (!map.IsMap()) fail(map, where, "expected a mapping of keys to values");
    std::set<std::string> seen;
    for (const auto& kv : map) {
      const auto key = yaml_key(kv.first, file_.string());
      const std::string full = where.empty() ? key : where + "." + key;
      if (!allowed.count(key)) fail(kv.first, full, "unknown key");
      if (!seen.insert(key).second) fail(kv.first, full, "given twice");
    }
  }
  template <class T>
  std::optional<T> get(const YAML::Node& map, const std::string& key, const std::string& where, const char* what) const {
    const YAML::Node n = map[key];
    const std::string full = where.empty() ? key : where + "." + key;
    if (!n) return std::nullopt;
    if (!n.IsScalar()) fail(n, full, std::string("expected ") + what);
    try {
      return n.as<T>();
    } catch (const YAML::Exception&) {
      fail(n, full, std::string("expected ") + what + ", got '" + n.Scalar() + "'");
    }
  }
  template <class T>
  T need(const YAML::Node& map, const std::string& key, const std::string& where, const char* what) const {
    auto v = get<T>(map, key, where, what);
    if (!v) fail(map, where.empty() ? key : where + "." + key, std::string("missing: expected ") + what);
    return *v;
  }
  double number(const YAML::Node& map, const std::string& key, const std::string& where, double lo) const {
    const double v = need<double>(map, key, where, "a number");
    if (!std::isfinite(v) || v <= lo) fail(map[key], where + "." + key, "expected a finite number above " + std::to_string(lo));
    return v;
  }
  std::optional<fs::path> path(const YAML::Node& map, const std::string& key, const std::string& where) const {
    auto s = get<std::string>(map, key, where, "a file path");
    if (!s) return std::nullopt;
    if (s->empty()) fail(map[key], where + "." + key, "expected a file path, got an empty string");
    return file_.parent_path() / *s;
  }
  const YAML::Node list(const YAML::Node& root, const std::string& key) const {
    const YAML::Node n = root[key];
    if (!n || !n.IsSequence() || n.size() == 0) fail(n ? n : root, key, "expected a non-empty list");
    return n;
  }
  const fs::path& file() const { return file_; }

 private:
  fs::path file_;
};

std::string item(const std::string& list, std::size_t i) { return list + "[" + std::to_string(i) + "]"; }

std::string read_id(const Reader& r, const YAML::Node& node, const std::string& where) {
  const auto id = r.need<std::string>(node, "id", where, "an id");
  if (id.empty() || id.find_first_of("/\\ \t") != std::string::npos || id == "." || id == "..")
    r.fail(node["id"], where + ".id", "expected a non-empty id without '/', '\\' or spaces (it names a folder)");
  return id;
}

std::string unique_id(const Reader& r, const YAML::Node& node, const std::string& where, std::set<std::string>& ids) {
  const std::string id = read_id(r, node, where);
  if (!ids.insert(id).second) r.fail(node["id"], where + ".id", "duplicate id '" + id + "'");
  return id;
}

void read_participants(const Reader& r, const YAML::Node& root, Manifest& m) {
  std::set<std::string> ids;
  const YAML::Node list = r.list(root, "participants");
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string where = item("participants", i);
    r.keys(list[i], where, {"id", "person", "calibration"});
    Participant p;
    p.id = unique_id(r, list[i], where, ids);
    p.person = r.get<std::string>(list[i], "person", where, "a person's name").value_or(p.id);
    p.calibration = r.path(list[i], "calibration", where);
    m.participants.push_back(std::move(p));
  }
}

void read_conditions(const Reader& r, const YAML::Node& root, Manifest& m) {
  std::set<std::string> ids;
  const YAML::Node list = r.list(root, "conditions");
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string where = item("conditions", i);
    r.keys(list[i], where, {"id", "scene", "bump"});
    Condition c;
    c.id = unique_id(r, list[i], where, ids);
    const auto scene = r.path(list[i], "scene", where);
    if (!scene) r.fail(list[i], where + ".scene", "missing: expected the condition's scene file");
    c.scene = *scene;
    if (const YAML::Node b = list[i]["bump"]) {
      r.keys(b, where + ".bump", {"diameter_mm", "height_mm", "centre_mm"});
      Bump bump;
      bump.diameter_mm = r.number(b, "diameter_mm", where + ".bump", 0);
      bump.height_mm = r.number(b, "height_mm", where + ".bump", 0);
      if (const YAML::Node cxy = b["centre_mm"]) {
        if (!cxy.IsSequence() || cxy.size() != 2) r.fail(cxy, where + ".bump.centre_mm", "expected [x, y] in mm (part frame)");
        try {
          bump.centre_mm = Vec2(cxy[0].as<double>(), cxy[1].as<double>());
        } catch (const YAML::Exception&) {
          r.fail(cxy, where + ".bump.centre_mm", "expected two numbers");
        }
        if (!bump.centre_mm->allFinite()) r.fail(cxy, where + ".bump.centre_mm", "expected finite numbers");
      }
      c.bump = bump;
    }
    m.conditions.push_back(std::move(c));
  }
}

void read_trials(const Reader& r, const YAML::Node& root, Manifest& m) {
  std::map<std::string, int> first_line;
  const YAML::Node list = r.list(root, "trials");
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string where = item("trials", i);
    const YAML::Node n = list[i];
    r.keys(n, where, {"id", "participant", "condition", "baseline", "worn", "both", "force_n"});
    Trial t;
    t.line = n.Mark().line + 1;
    t.id = read_id(r, n, where);
    t.participant = r.need<std::string>(n, "participant", where, "a participant's id");
    t.condition = r.need<std::string>(n, "condition", where, "a condition's id");
    const std::string at = "line " + std::to_string(t.line) + ", " + where + ": ";
    if (const auto [it, fresh] = first_line.emplace(t.id, t.line); !fresh)
      t.problem = at + "duplicate trial id '" + t.id + "' (first at line " + std::to_string(it->second) + "); give each trial its own id";
    else if (!m.has_participant(t.participant))
      t.problem = at + "no participant has the id '" + t.participant + "'";
    else if (!m.has_condition(t.condition))
      t.problem = at + "no condition has the id '" + t.condition + "'";
    t.baseline = r.path(n, "baseline", where).value_or(fs::path());
    t.worn = r.path(n, "worn", where).value_or(fs::path());
    t.both = r.path(n, "both", where).value_or(fs::path());
    const bool two = !t.baseline.empty() && !t.worn.empty(), one = !t.both.empty();
    if (two == one || (!two && (!t.baseline.empty() || !t.worn.empty())))
      r.fail(n, where, "expected either baseline and worn, or both (one capture holding both phases)");
    if (n["force_n"]) t.force_n = r.number(n, "force_n", where, 0);
    m.trials.push_back(std::move(t));
  }
}

void read_analysis(const Reader& r, const YAML::Node& root, Manifest& m) {
  const YAML::Node a = root["analysis"];
  if (!a) return;
  r.keys(a, "analysis", {"pressure", "window_frames", "profile"});
  m.analysis.pressure = r.get<bool>(a, "pressure", "analysis", "true or false").value_or(false);
  m.analysis.window_frames = r.get<int>(a, "window_frames", "analysis", "a whole number").value_or(0);
  if (const YAML::Node p = a["profile"]) {
    r.keys(p, "analysis.profile", {"length_mm", "angle_step_deg", "sample_mm"});
    if (p["length_mm"]) m.analysis.profile.length_mm = r.number(p, "length_mm", "analysis.profile", 0);
    if (p["angle_step_deg"]) m.analysis.profile.angle_step_deg = r.number(p, "angle_step_deg", "analysis.profile", 0);
    if (p["sample_mm"]) m.analysis.profile.sample_mm = r.number(p, "sample_mm", "analysis.profile", 0);
  }
  try {
    m.analysis.validate();
  } catch (const std::invalid_argument& e) {
    r.fail(a, "analysis", e.what());
  }
}

}  // namespace

void AnalysisOptions::validate() const {
  if (window_frames < 0) throw std::invalid_argument("window_frames = " + std::to_string(window_frames) + ": must be ≥ 0");
  profile.validate();
}

bool Manifest::has_participant(const std::string& id) const {
  for (const auto& p : participants)
    if (p.id == id) return true;
  return false;
}

bool Manifest::has_condition(const std::string& id) const {
  for (const auto& c : conditions)
    if (c.id == id) return true;
  return false;
}

const Participant& Manifest::participant(const std::string& id) const {
  for (const auto& p : participants)
    if (p.id == id) return p;
  throw std::out_of_range("no participant " + id);
}

const Condition& Manifest::condition(const std::string& id) const {
  for (const auto& c : conditions)
    if (c.id == id) return c;
  throw std::out_of_range("no condition " + id);
}

Manifest read_manifest(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    throw InputError(path.string(), "", fs::exists(path, ec) ? "is not a regular file" : "does not exist",
                     "give the study manifest (YAML)");
  YAML::Node root;
  try {
    root = YAML::LoadFile(path.string());
  } catch (const YAML::Exception& e) {
    throw InputError(path.string(), "line " + std::to_string(e.mark.line + 1), "not valid YAML: " + e.msg);
  }
  const Reader r(path);
  r.keys(root, "", {"schema", "study", "participants", "conditions", "trials", "analysis"});
  if (auto schema = r.get<std::string>(root, "schema", "", "a schema name"); schema && *schema != "clearfit.study/1")
    r.fail(root["schema"], "schema", "expected clearfit.study/1, got '" + *schema + "'");
  Manifest m;
  m.path = path;
  m.study = r.get<std::string>(root, "study", "", "the study's name").value_or(path.stem().string());
  read_participants(r, root, m);
  read_conditions(r, root, m);
  read_trials(r, root, m);
  read_analysis(r, root, m);
  if (m.analysis.pressure)
    for (Trial& t : m.trials)
      if (t.problem.empty() && !m.participant(t.participant).calibration)
        t.problem = "line " + std::to_string(t.line) + ", trial '" + t.id +
                    "': analysis.pressure asks for kPa but participant '" + t.participant +
                    "' has no calibration (give it one, or set analysis.pressure: false)";
  return m;
}

}  // namespace clearfit::study
