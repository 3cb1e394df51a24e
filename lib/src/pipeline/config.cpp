// The one place that parses YAML. Everything else sees validated, typed structs.
#include "pcdp/pipeline/config.hpp"

#include <glob.h>
#include <sys/stat.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/geotiff.hpp"
#include "pcdp/io/input_file.hpp"
#include "pcdp/pipeline/stage.hpp"

namespace fs = std::filesystem;

namespace pcdp {

// ---- schemas of the fixed blocks ---------------------------------------------------------

const OptionSchema& sensor_schema() {
  static const OptionSchema s = [] {
    constexpr double kPi = 3.14159265358979323846;
    OptionSchema v{
        opt_double("range_min", 0.1, 0.0, std::nullopt, "m",
                   "shortest valid calibrated range; shorter returns are labelled out_of_range"),
        opt_double("range_max", 30.0, 0.0, std::nullopt, "m",
                   "longest valid calibrated range; longer returns are labelled out_of_range"),
        opt_double("beam_divergence", 0.004, 0.0, 0.2, "rad",
                   "full-angle beam divergence (alpha, Liu et al. 2005)"),
        opt_double("transceiver_separation", 0.04, 0.0, 1.0, "m",
                   "transmitter-receiver separation (s - q, Liu et al. 2005)"),
        opt_enum("transceiver_angle", "fixed", {"fixed", "mirror"},
                 "fixed: always separated (theta = 0); mirror: theta = bearing + offset"),
        opt_double("transceiver_angle_offset", 0.0, -kPi, kPi, "rad",
                   "offset added to the bearing for the mirror transceiver angle"),
        opt_double("min_amplitude", 18.0, 0.0, std::nullopt, "",
                   "minimum detectable amplitude (sensor units)"),
        opt_double("range_sigma", 0.0053, 0.0, 1.0, "m",
                   "1-sigma range noise (Ye & Borenstein eq. 6)"),
        opt_double("range_calibration.k", 1.0, 0.5, 2.0, "",
                   "scale of the linear range calibration: true = k * measured + b"),
        opt_double("range_calibration.b", 0.0, -1.0, 1.0, "m",
                   "offset of the linear range calibration: true = k * measured + b"),
        opt_double("encoder_resolution", 0.0012566, 0.0, 0.1, "rad",
                   "nod-encoder resolution (0.072 deg in Broten & Collier)"),
        opt_double("encoder_latency", 0.0, -1.0, 1.0, "s",
                   "a line's encoder reading describes the nod at its last return's stamp minus this"),
        opt_double("encoder_latency_sigma", 0.0, 0.0, 1.0, "s",
                   "1-sigma uncertainty of encoder_latency (times the nod rate, a nod error)"),
        opt_double("bearing_resolution", 0.0, 0.0, 0.1, "rad",
                   "quantization of the in-plane beam angle (uniform: sigma = resolution / sqrt 12)"),
    };
    v[1].min_exclusive = true;   // range_max > 0
    v[8].min_exclusive = true;
    return v;
  }();
  return s;
}

const OptionSchema& mount_schema() {
  static const OptionSchema s = [] {
    constexpr double kPi = 3.14159265358979323846;
    return OptionSchema{
        opt_double("x", 0.0, -100.0, 100.0, "m", "nod-axis origin in the vehicle frame, forward"),
        opt_double("y", 0.0, -100.0, 100.0, "m", "nod-axis origin in the vehicle frame, left"),
        opt_double("z", 0.0, -100.0, 100.0, "m", "nod-axis origin in the vehicle frame, up"),
        opt_double("roll", 0.0, -kPi, kPi, "rad", "mount roll (rpy_order applies)"),
        opt_double("pitch", 0.0, -kPi, kPi, "rad",
                   "mount pitch (rpy_order applies; positive tips the laser's x axis down)"),
        opt_double("yaw", 0.0, -kPi, kPi, "rad", "mount yaw (rpy_order applies)"),
    };
  }();
  return s;
}

const OptionSchema& pose_sigma_schema() {
  static const OptionSchema s = {
      opt_double("position", 0.005, 0.0, 100.0, "m", "1-sigma position uncertainty of the poses"),
      opt_double("rpy", 0.00035, 0.0, 1.0, "rad", "1-sigma roll/pitch/yaw uncertainty of the poses"),
  };
  return s;
}

const OptionSchema& top_level_schema() {
  static const OptionSchema s = {
      opt_bool("allow_empty_output", false,
               "false: a run that keeps no return, or leaves more than half of its in-range returns without "
               "a pose (a time-base mismatch?), fails with exit 3 before writing; true: it writes and warns"),
      opt_string("crs", "",
                 "the map frame's coordinate reference system: EPSG:<code> (or its WKT) of a projected CRS in "
                 "metres, checked against PROJ's database; written as elevation.tif's GeoKeys, kept by merge; "
                 "empty: none"),
  };
  return s;
}

Override parse_override(const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw ConfigError("--set '" + text + "': expected key=value (e.g. sensor.min_amplitude=20)");
  for (unsigned char c : text)  // YAML would fold a newline into a space: a path would name another file
    if (c < 0x20 || c == 0x7f)
      throw ConfigError("--set " + text.substr(0, eq) + ": the value contains a control character (byte " +
                        std::to_string(static_cast<int>(c)) + "): refused");
  return {text.substr(0, eq), text.substr(eq + 1)};
}

namespace {

const std::vector<std::string> kTopKeys = {"description", "rpy_order",  "input",  "output_dir",        "mount",
                                           "sensor",      "pose_sigma", "stages", "allow_empty_output", "crs"};
const std::vector<std::string> kInputKeys = {"scans", "poses"};

std::string node_kind(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Sequence: return "a list";
    case YAML::NodeType::Map: return "a mapping";
    case YAML::NodeType::Null: return "empty";
    default: return "a value";
  }
}

/// Builds "where" strings and knows which keys came from --set.
class Context {
 public:
  Context(std::string source, std::string base_dir) : source_(std::move(source)), base_(std::move(base_dir)) {}

  void add_override(const std::string& key, const std::string& text) { overrides_[key] = text; }
  bool overridden(const std::string& key) const { return overrides_.count(key) != 0; }

  std::string where(const std::string& key, const YAML::Node& n) const {
    auto it = overrides_.find(key);
    if (it != overrides_.end()) return "--set " + it->second;
    std::ostringstream os;
    os << source_;
    if (n.IsDefined() && n.Mark().line >= 0) os << ":" << n.Mark().line + 1;
    return os.str();
  }

  /// Paths in the file resolve against the file's folder; paths given by --set against the
  /// working directory, as a user typing them expects.
  std::string resolve(const std::string& key, const std::string& p) const {
    for (unsigned char c : p)
      if (c < 0x20 || c == 0x7f)
        throw ConfigError(source_ + ": key '" + key + "': the path contains a control character (byte " +
                          std::to_string(static_cast<int>(c)) + "): refused");
    if (p.empty() || fs::path(p).is_absolute() || overridden(key)) return p;
    return (fs::path(base_) / p).lexically_normal().string();
  }

  const std::string& source() const { return source_; }

 private:
  std::string source_;
  std::string base_;
  std::map<std::string, std::string> overrides_;
};

[[noreturn]] void fail(const std::string& where, const std::string& msg) {
  throw ConfigError(where + ": " + msg);
}

std::string scalar_of(const Context& ctx, const std::string& key, const YAML::Node& n,
                      const std::string& what) {
  if (!n.IsScalar())
    fail(ctx.where(key, n), what + " '" + key + "' must be a single value, but it is " + node_kind(n));
  return n.Scalar();
}

/// Flattens nested mappings into dotted keys: {a: {b: 1}} -> "a.b" -> node.
void flatten(const Context& ctx, const std::string& prefix, const std::string& full_prefix,
             const YAML::Node& map, std::vector<std::pair<std::string, YAML::Node>>& out,
             int depth = 0) {
  if (depth > 8) fail(ctx.where(full_prefix, map), "'" + full_prefix + "' is nested too deeply");
  for (const auto& kv : map) {
    const std::string k = kv.first.Scalar();
    const std::string key = prefix.empty() ? k : prefix + "." + k;
    if (kv.second.IsMap())
      flatten(ctx, key, full_prefix + "." + k, kv.second, out, depth + 1);
    else
      out.emplace_back(key, kv.second);
  }
}

/// Validates a block (a mapping) against a schema. `what` names it in messages ("sensor",
/// "stage 'reg' (register)"); `key_prefix` is the dotted prefix used by --set.
OptionValues validate_block(const Context& ctx, const YAML::Node& block, const OptionSchema& schema,
                            const std::string& what, const std::string& key_prefix,
                            const std::set<std::string>& skip = {}) {
  OptionValues values;
  std::vector<std::string> names;
  for (const auto& s : schema) names.push_back(s.name);
  if (block.IsDefined() && !block.IsNull()) {
    if (!block.IsMap())
      fail(ctx.where(key_prefix, block), what + " must be a mapping of options, but it is " + node_kind(block));
    std::vector<std::pair<std::string, YAML::Node>> flat;
    flatten(ctx, "", key_prefix, block, flat);
    for (const auto& entry : flat) {
      const std::string& key = entry.first;
      const YAML::Node& node = entry.second;
      if (skip.count(key)) continue;
      const std::string full = key_prefix.empty() ? key : key_prefix + "." + key;
      auto it = std::find_if(schema.begin(), schema.end(), [&](const OptionSpec& s) { return s.name == key; });
      if (it == schema.end())
        fail(ctx.where(full, node), what + ": unknown option '" + key + "'" + did_you_mean(key, names) +
                                        "; known options: " + [&] {
                                          std::string s;
                                          for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
                                          return s;
                                        }());
      if (node.IsNull())
        fail(ctx.where(full, node), what + ": option '" + key + "' has no value");
      const std::string text = scalar_of(ctx, full, node, what + ": option");
      OptionValue v;
      if (auto err = parse_option_value(*it, text, v))
        fail(ctx.where(full, node), what + ": option '" + key + "' = '" + text + "' " + *err);
      values.set(key, v);
      values.mark_given(key);
    }
  }
  for (const auto& s : schema) {
    if (values.has(s.name)) continue;
    if (s.required)
      fail(ctx.where(key_prefix, block), what + ": required option '" + s.name + "' is missing (" + s.doc + ")");
    values.set(s.name, s.default_value);
  }
  return values;
}

/// Walks the YAML event stream and refuses what yaml-cpp would silently accept or choke on:
/// a key given twice in one mapping (at any depth), a second document, nesting deeper than
/// kMaxDepth levels (block or flow: the node tree and its users recurse), a key that is itself
/// a mapping or a list, and text that is not UTF-8. Each error names the source, the line, the
/// key path and the rule.
class StrictYamlCheck final : public YAML::EventHandler {
 public:
  static constexpr std::size_t kMaxDepth = 64;

  /// `bytes_ok`: scalar values may hold bytes that are not UTF-8 (paths given on the command line).
  StrictYamlCheck(std::string source, bool bytes_ok) : source_(std::move(source)), bytes_ok_(bytes_ok) {}

  void OnDocumentStart(const YAML::Mark& mark) override {
    if (++documents_ > 1)
      throw ConfigError(at(mark) + ": a second YAML document begins here; a pipeline is one document "
                                   "(remove the '---' line and what follows, or merge the two)");
  }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& mark, YAML::anchor_t anchor) override {
    if (anchor) anchored_[anchor] = kNullKey;
    node(mark, kNullKey, false);
  }
  void OnAlias(const YAML::Mark& mark, YAML::anchor_t anchor) override {
    auto it = anchored_.find(anchor);
    // An alias of a mapping or a list as a key is refused like the mapping itself.
    node(mark, it == anchored_.end() ? std::string() : it->second, it == anchored_.end());
  }
  void OnScalar(const YAML::Mark& mark, const std::string&, YAML::anchor_t anchor, const std::string& value) override {
    const bool key = !stack_.empty() && stack_.back().map && stack_.back().expect_key;
    if (!key && bytes_ok_) {
    } else if (auto bad = invalid_utf8_offset(value)) {
      const std::string path = key ? path_of_key(value) : child_path();
      throw ConfigError(at(mark) + ": " + (key ? "key" : "the value of '" + path + "'") + ": byte " +
                        std::to_string(*bad) + " (0x" + hex(value[*bad]) + ") is not valid UTF-8 (YAML text is " +
                        "Unicode; a file name in other bytes can be matched by a glob or given with --set)");
    }
    if (anchor) anchored_[anchor] = value;
    node(mark, value, false);
  }
  void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    open(mark, false);
  }
  void OnSequenceEnd() override { stack_.pop_back(); }
  void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    open(mark, true);
  }
  void OnMapEnd() override { stack_.pop_back(); }

 private:
  static constexpr const char* kNullKey = "\x01null";  // the null key (`~:` or `: x`), apart from "null"

  struct Frame {
    bool map = false;
    std::string path;            // of this container, dotted ("stages[1].sensor")
    bool expect_key = true;      // map: the next node is a key
    std::string key;             // map: the key whose value comes next
    std::size_t index = 0;       // sequence: the next item's index
    std::map<std::string, int> lines;  // map: key -> its line (1-based)
  };

  std::string at(const YAML::Mark& mark) const {
    std::string s = source_;
    if (mark.line >= 0) s += ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
    return s;
  }
  static std::string hex(char c) {
    const char* d = "0123456789ABCDEF";
    const auto u = static_cast<unsigned char>(c);
    return {d[u >> 4], d[u & 15]};
  }
  static std::string shown(const std::string& key) { return key == kNullKey ? "null" : key; }
  std::string path_of_key(const std::string& key) const {
    const std::string& p = stack_.back().path;
    return p.empty() ? shown(key) : p + "." + shown(key);
  }
  /// The path of the node that comes next (a value or a list item).
  std::string child_path() const {
    if (stack_.empty()) return "";
    const Frame& f = stack_.back();
    if (f.map) return path_of_key(f.key);
    return f.path + "[" + std::to_string(f.index) + "]";
  }

  /// A node begins: a key of the mapping on top, or a value / list item.
  void node(const YAML::Mark& mark, const std::string& text, bool container) {
    if (stack_.empty()) return;
    Frame& f = stack_.back();
    if (!f.map) {
      ++f.index;
      return;
    }
    if (!f.expect_key) {  // a value: its events (if a container) come on a frame of their own
      f.expect_key = true;
      return;
    }
    if (container)
      throw ConfigError(at(mark) + ": a key in '" + (f.path.empty() ? std::string("(top level)") : f.path) +
                        "' is a mapping or a list; keys must be plain names (an unclosed '[' or '{' reads so too)");
    const int line = mark.line + 1;
    const auto [it, fresh] = f.lines.emplace(text, line);
    if (!fresh)
      throw ConfigError(at(mark) + ": duplicate key '" + path_of_key(text) + "': given at line " +
                        std::to_string(it->second) + " and again at line " + std::to_string(line) +
                        " (a key may appear once in a mapping; remove one)");
    f.key = text;
    f.expect_key = false;
  }

  void open(const YAML::Mark& mark, bool map) {
    const bool is_key = !stack_.empty() && stack_.back().map && stack_.back().expect_key;
    if (is_key) node(mark, "", true);  // throws
    const std::string path = child_path();
    node(mark, "", true);
    if (stack_.size() >= kMaxDepth)
      throw ConfigError(at(mark) + ": not valid YAML: nested more than " + std::to_string(kMaxDepth) +
                        " levels deep (at '" + (path.size() > 60 ? path.substr(0, 60) + "..." : path) + "')");
    Frame f;
    f.map = map;
    f.path = path;
    stack_.push_back(std::move(f));
  }

  std::string source_;
  bool bytes_ok_;
  int documents_ = 0;
  std::vector<Frame> stack_;
  std::map<YAML::anchor_t, std::string> anchored_;
};

/// Runs StrictYamlCheck over `text` (throws ConfigError, or YAML::Exception for syntax errors).
void check_yaml_strictly(const std::string& text, const std::string& source, bool bytes_ok) {
  std::istringstream in(text);
  YAML::Parser parser(in);
  StrictYamlCheck check(source, bytes_ok);
  while (parser.HandleNextDocument(check)) {
  }
}

std::string yaml_error(const std::string& source, const YAML::Exception& e) {
  std::ostringstream os;
  os << source;
  if (e.mark.line >= 0) os << ":" << e.mark.line + 1 << ":" << e.mark.column + 1;
  os << ": not valid YAML: " << e.msg;
  return os.str();
}

YAML::Node load_yaml(const std::string& text, const std::string& source) {
  // The strict walk first: it bounds the depth before the tree is built (yaml-cpp's own guard
  // only says "bad file", and a pipeline needs a handful of levels) and refuses duplicate keys
  // and second documents, which YAML::Load would silently merge or drop.
  try {
    check_yaml_strictly(text, source, false);
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(yaml_error(source, e));
  }
}

std::string instance_name(const YAML::Node& st) {
  if (st.IsMap() && st["name"] && st["name"].IsScalar()) return st["name"].Scalar();
  if (st.IsMap() && st["type"] && st["type"].IsScalar()) return st["type"].Scalar();
  return "";
}

/// Writes a --set override into the YAML tree (validated afterwards like any other key).
void apply_override(YAML::Node root, const Override& ov, Context& ctx) {
  std::vector<std::string> parts;
  std::stringstream ss(ov.key);
  for (std::string p; std::getline(ss, p, '.');) {
    if (p.empty()) throw ConfigError("--set " + ov.key + "=" + ov.value + ": empty key component");
    parts.push_back(p);
  }
  const std::string shown = "--set " + ov.key + "=" + ov.value;
  if (auto bad = invalid_utf8_offset(ov.key))
    throw ConfigError(shown + ": byte " + std::to_string(*bad) + " of the key is not valid UTF-8 (keys are UTF-8)");
  // Paths are bytes on Linux: a file name that is not UTF-8 may be given for them; every other
  // value (names, options) is text.
  const bool path_key = ov.key == "output_dir" || ov.key == "input.poses" || ov.key == "input.scans";
  if (auto bad = invalid_utf8_offset(ov.value); bad && !path_key)
    throw ConfigError(shown + ": byte " + std::to_string(*bad) + " of the value of '" + ov.key +
                      "' is not valid UTF-8 (only paths may hold other bytes)");
  YAML::Node value;
  try {
    // The value is YAML too, held to the same rules as the file (one document, each key once).
    check_yaml_strictly(ov.value, "--set " + ov.key, true);
    value = YAML::Load(ov.value);
  } catch (const YAML::Exception&) {
    value = YAML::Node(ov.value);  // not YAML: the text as it is
  }
  if (!value.IsDefined() || value.IsNull()) value = YAML::Node(ov.value);
  ctx.add_override(ov.key, ov.key + "=" + ov.value);

  YAML::Node cur = root;
  std::size_t i = 0;
  if (parts[0] == "stages") {
    if (parts.size() < 3)
      throw ConfigError("--set " + ov.key + "=" + ov.value +
                        ": stage options are set as stages.<instance name>.<option>");
    YAML::Node stages = root["stages"];
    std::vector<std::string> names;
    YAML::Node target;
    if (stages.IsSequence())
      for (std::size_t k = 0; k < stages.size(); ++k) {
        const YAML::Node st = stages[k];
        names.push_back(instance_name(st));
        if (instance_name(st) == parts[1]) target.reset(st);  // reset: re-point, never assign into
      }
    if (!target.IsDefined() || !target.IsMap()) {
      std::string list;
      for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
      throw ConfigError("--set " + ov.key + "=" + ov.value + ": no stage instance named '" + parts[1] + "'" +
                        did_you_mean(parts[1], names) + "; instances: " + (list.empty() ? "(none)" : list));
    }
    cur.reset(target);
    i = 2;
  }
  for (; i + 1 < parts.size(); ++i) {
    YAML::Node next = cur[parts[i]];
    if (!next.IsDefined() || next.IsNull()) {
      cur[parts[i]] = YAML::Node(YAML::NodeType::Map);
      next.reset(cur[parts[i]]);
    }
    if (!next.IsMap())
      throw ConfigError("--set " + ov.key + "=" + ov.value + ": '" + parts[i] + "' is not a mapping");
    cur.reset(next);
  }
  cur[parts.back()] = value;
}

bool has_glob_chars(const std::string& p) { return p.find_first_of("*?[") != std::string::npos; }

// Up front, before any reading: the file must exist and be a regular file (not a FIFO, device,
// socket or directory, and not a symlink loop), so that no reader blocks or reads without end.
void check_input_file(const std::string& where, const std::string& key, const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 && errno == ENOENT)
    throw InputError(where + ": " + key + ": file '" + path + "' does not exist");
  const std::string problem = io::regular_file_problem(path, key == "input.poses" ? "pose file" : "pass file");
  if (!problem.empty()) throw InputError(where + ": " + key + ": '" + path + "' " + problem);
}

std::vector<std::string> expand_scans(const std::string& where, const std::vector<std::string>& patterns,
                                      bool check) {
  std::vector<std::string> out;
  for (const auto& p : patterns) {
    if (!has_glob_chars(p)) {
      if (check) check_input_file(where, "input.scans", p);
      out.push_back(p);
      continue;
    }
    glob_t g{};
    const int rc = ::glob(p.c_str(), 0, nullptr, &g);
    std::vector<std::string> matched;
    if (rc == 0)
      for (std::size_t i = 0; i < g.gl_pathc; ++i) matched.emplace_back(g.gl_pathv[i]);
    ::globfree(&g);
    std::sort(matched.begin(), matched.end());  // lexicographic, whatever the locale (docs/data_contract.md)
    matched.erase(std::remove_if(matched.begin(), matched.end(),
                                 [](const std::string& m) {
                                   std::error_code ec;  // a symlink loop is no directory: refused below
                                   return fs::is_directory(m, ec);
                                 }),
                  matched.end());
    if (matched.empty() && check) throw InputError(where + ": input.scans: no file matches '" + p + "'");
    if (check)
      for (const auto& m : matched) check_input_file(where, "input.scans", m);
    out.insert(out.end(), matched.begin(), matched.end());
  }
  if (check) {
    std::set<std::string> seen;
    for (const auto& f : out) {
      std::error_code ec;
      std::string canon = fs::weakly_canonical(f, ec).string();
      if (ec) canon = fs::absolute(f, ec).lexically_normal().string();
      if (!seen.insert(canon).second)
        throw InputError(where + ": input.scans: pass file '" + f +
                         "' is listed twice (line indices must be unique within a run)");
    }
  }
  return out;
}

PipelineConfig build(YAML::Node root, Context& ctx, const LoadOptions& opts) {
  for (const auto& ov : opts.overrides) {
    if (!root.IsMap()) break;
    apply_override(root, ov, ctx);
  }
  const std::string file = ctx.source();
  if (!root.IsDefined() || root.IsNull())
    fail(file, "the pipeline file is empty; it needs at least 'input' and 'stages'");
  if (!root.IsMap()) fail(ctx.where("", root), "the pipeline must be a mapping of keys, but it is " + node_kind(root));

  PipelineConfig cfg;
  cfg.source = file;
  for (const auto& kv : root) {
    const std::string k = kv.first.Scalar();
    if (std::find(kTopKeys.begin(), kTopKeys.end(), k) == kTopKeys.end())
      fail(ctx.where(k, kv.first), "unknown key '" + k + "'" + did_you_mean(k, kTopKeys) +
                                       "; known keys: description, rpy_order, input, output_dir, "
                                       "mount, sensor, pose_sigma, stages, allow_empty_output, crs");
  }
  {
    YAML::Node top(YAML::NodeType::Map);
    for (const auto& o : top_level_schema())
      if (root[o.name]) top[o.name] = root[o.name];
    const OptionValues v = validate_block(ctx, top, top_level_schema(), "pipeline", "");
    cfg.allow_empty_output = v.get_bool("allow_empty_output");
  }

  // crs: the map frame's coordinate reference system, written as elevation.tif's GeoKeys.
  if (root["crs"] && !root["crs"].IsNull()) {
    const std::string v = scalar_of(ctx, "crs", root["crs"], "key");
    if (v.empty()) fail(ctx.where("crs", root["crs"]), "'crs' is empty (give EPSG:<code>, or leave the key out)");
    try {
      cfg.crs = io::normalize_crs(v);
    } catch (const std::invalid_argument& e) {
      fail(ctx.where("crs", root["crs"]), std::string("crs = ") + e.what() +
                                              " (crs is EPSG:<code> of a projected CRS in metres, e.g. EPSG:32632, "
                                              "or its WKT)");
    }
  }

  if (root["rpy_order"]) {
    const std::string v = scalar_of(ctx, "rpy_order", root["rpy_order"], "key");
    if (v != "xyz" && v != "zyx")
      fail(ctx.where("rpy_order", root["rpy_order"]),
           "rpy_order = '" + v + "' must be one of xyz|zyx (xyz: Broten & Collier 6.2; zyx: REP 103)");
    cfg.rpy_order = rpy_order_from_name(v);
  }

  // input
  const YAML::Node input = root["input"];
  if (!input || input.IsNull()) fail(file, "required key 'input' is missing (input.scans: pass files or a glob)");
  if (!input.IsMap()) fail(ctx.where("input", input), "'input' must be a mapping with 'scans' and 'poses'");
  for (const auto& kv : input) {
    const std::string k = kv.first.Scalar();
    if (std::find(kInputKeys.begin(), kInputKeys.end(), k) == kInputKeys.end())
      fail(ctx.where("input." + k, kv.first), "input: unknown key '" + k + "'" + did_you_mean(k, kInputKeys) +
                                                  "; known keys: scans, poses");
  }
  const YAML::Node scans = input["scans"];
  if (!scans || scans.IsNull()) fail(ctx.where("input", input), "required key 'input.scans' is missing (pass files or a glob)");
  if (scans.IsScalar()) {
    cfg.scan_patterns.push_back(ctx.resolve("input.scans", scans.Scalar()));
  } else if (scans.IsSequence()) {
    for (const auto& s : scans) cfg.scan_patterns.push_back(ctx.resolve("input.scans", scalar_of(ctx, "input.scans", s, "entry of")));
  } else {
    fail(ctx.where("input.scans", scans), "'input.scans' must be a path, a glob or a list of them");
  }
  if (cfg.scan_patterns.empty()) fail(ctx.where("input.scans", scans), "'input.scans' is an empty list");
  if (input["poses"] && !input["poses"].IsNull())
    cfg.poses = ctx.resolve("input.poses", scalar_of(ctx, "input.poses", input["poses"], "key"));

  // output
  if (!opts.output_dir.empty()) {
    for (unsigned char c : opts.output_dir)
      if (c < 0x20 || c == 0x7f) throw ConfigError("--output-dir: the path contains a control character: refused");
    cfg.output_dir = opts.output_dir;
  } else {
    const YAML::Node od = root["output_dir"];
    if (!od || od.IsNull()) {
      // Not given: out/<the pipeline file's name without .yaml>, relative to the working directory
      // (where the user runs, never beside a shipped or installed pipeline file).
      const std::string stem = fs::path(file).stem().string();
      cfg.output_dir = (fs::path("out") / (stem.empty() || stem == "." || stem == ".." ? "pipeline" : stem)).string();
    } else {
      cfg.output_dir = ctx.resolve("output_dir", scalar_of(ctx, "output_dir", od, "key"));
      if (cfg.output_dir.empty()) fail(ctx.where("output_dir", od), "'output_dir' is empty");
    }
  }

  // fixed blocks
  const OptionValues mount = validate_block(ctx, root["mount"], mount_schema(), "mount", "mount");
  cfg.mount.translation = {mount.get_double("x"), mount.get_double("y"), mount.get_double("z")};
  cfg.mount.rpy = {mount.get_double("roll"), mount.get_double("pitch"), mount.get_double("yaw")};

  const OptionValues sensor = validate_block(ctx, root["sensor"], sensor_schema(), "sensor", "sensor");
  SensorParams& s = cfg.sensor;
  s.range_min = sensor.get_double("range_min");
  s.range_max = sensor.get_double("range_max");
  s.beam_divergence = sensor.get_double("beam_divergence");
  s.transceiver_separation = sensor.get_double("transceiver_separation");
  s.transceiver_angle = sensor.get_string("transceiver_angle") == "mirror" ? TransceiverAngle::kMirror
                                                                          : TransceiverAngle::kFixed;
  s.transceiver_angle_offset = sensor.get_double("transceiver_angle_offset");
  s.min_amplitude = sensor.get_double("min_amplitude");
  s.range_sigma = sensor.get_double("range_sigma");
  s.range_k = sensor.get_double("range_calibration.k");
  s.range_b = sensor.get_double("range_calibration.b");
  s.encoder_resolution = sensor.get_double("encoder_resolution");
  s.encoder_latency = sensor.get_double("encoder_latency");
  s.encoder_latency_sigma = sensor.get_double("encoder_latency_sigma");
  s.bearing_resolution = sensor.get_double("bearing_resolution");
  if (s.range_min >= s.range_max)
    fail(ctx.where("sensor.range_max", root["sensor"]["range_max"]),
         "sensor: range_min (" + format_value(s.range_min) + " m) must be less than range_max (" +
             format_value(s.range_max) + " m)");

  const OptionValues ps = validate_block(ctx, root["pose_sigma"], pose_sigma_schema(), "pose_sigma", "pose_sigma");
  cfg.pose_sigma.position = ps.get_double("position");
  cfg.pose_sigma.rpy = ps.get_double("rpy");
  cfg.blocks = {{"mount", mount}, {"sensor", sensor}, {"pose_sigma", ps}};

  // stages
  const YAML::Node stages = root["stages"];
  if (!stages || stages.IsNull()) fail(file, "required key 'stages' is missing: a pipeline needs at least one stage");
  if (!stages.IsSequence()) fail(ctx.where("stages", stages), "'stages' must be a list of stages");
  if (stages.size() == 0) fail(ctx.where("stages", stages), "the pipeline is empty: 'stages' lists no stage");
  std::set<std::string> names;
  for (const auto& st : stages) {
    StageConfig sc;
    sc.where = ctx.where("", st);
    if (!st.IsMap()) fail(sc.where, "each stage must be a mapping with a 'type', but this one is " + node_kind(st));
    const YAML::Node type = st["type"];
    if (!type || !type.IsScalar()) fail(sc.where, "stage has no 'type' (one of: " + [] {
      std::string s2;
      for (const auto& n : stage_type_names()) s2 += (s2.empty() ? "" : ", ") + n;
      return s2;
    }() + ")");
    sc.type = type.Scalar();
    const StageInfo* info = find_stage(sc.type);
    if (!info) {
      std::string list;
      for (const auto& n : stage_type_names()) list += (list.empty() ? "" : ", ") + n;
      fail(ctx.where("", type), "unknown stage type '" + sc.type + "'" + did_you_mean(sc.type, stage_type_names()) +
                                    "; known stages: " + list);
    }
    sc.name = instance_name(st);
    if (!names.insert(sc.name).second)
      fail(sc.where, "two stage instances are named '" + sc.name + "'; give each a unique 'name'");
    sc.options = validate_block(ctx, st, info->schema, "stage '" + sc.name + "' (" + sc.type + ")",
                                "stages." + sc.name, {"type", "name"});
    cfg.stages.push_back(std::move(sc));
  }

  cfg.scans = expand_scans(ctx.where("input.scans", scans), cfg.scan_patterns, opts.check_inputs);
  if (opts.check_inputs && !cfg.poses.empty())
    check_input_file(ctx.where("input.poses", input["poses"]), "input.poses", cfg.poses);
  return cfg;
}

}  // namespace

namespace detail {
OptionValues validate_yaml_block(const std::string& source, const YAML::Node& block, const OptionSchema& schema,
                                 const std::string& what, const std::string& key_prefix) {
  const Context ctx(source, ".");
  return validate_block(ctx, block, schema, what, key_prefix);
}
YAML::Node parse_yaml(const std::string& text, const std::string& source) { return load_yaml(text, source); }
std::string where(const std::string& source, const YAML::Node& n) { return Context(source, ".").where("", n); }
}  // namespace detail

PipelineConfig load_pipeline_from_string(const std::string& yaml, const std::string& source_name,
                                         const std::string& base_dir, const LoadOptions& opts) {
  Context ctx(source_name, base_dir);
  YAML::Node root = load_yaml(yaml, source_name);
  return build(root, ctx, opts);
}

PipelineConfig load_pipeline(const std::string& path, const LoadOptions& opts) {
  if (const std::string problem = io::regular_file_problem(path, "pipeline file"); !problem.empty()) {
    const bool missing = problem.rfind("cannot open", 0) == 0;  // "cannot read ...": the wording for a missing file
    throw ConfigError(path + ": " + (missing ? "cannot read" + problem.substr(11) : problem));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path + ": cannot read the pipeline file (" + std::strerror(errno) + ")");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string base = fs::path(path).parent_path().string();
  return load_pipeline_from_string(ss.str(), path, base.empty() ? "." : base, opts);
}

}  // namespace pcdp
