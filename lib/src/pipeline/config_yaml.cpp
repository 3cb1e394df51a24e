// Reading pipeline YAML: the strict event-stream check, the "where" of a key, --set overrides
// and the validation of a block against its option schema (config_yaml.hpp).
#include "pipeline/config_yaml.hpp"

#include <yaml-cpp/eventhandler.h>

#include <algorithm>

namespace pcdp::config_yaml {

std::string node_kind(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Sequence: return "a list";
    case YAML::NodeType::Map: return "a mapping";
    case YAML::NodeType::Null: return "empty";
    default: return "a value";
  }
}

[[noreturn]] void fail(const std::string& where, const std::string& msg) {
  throw ConfigError(where + ": " + msg);
}

std::string scalar_of(const Context& ctx, const std::string& key, const YAML::Node& n, const std::string& what) {
  if (!n.IsScalar())
    fail(ctx.where(key, n), what + " '" + key + "' must be a single value, but it is " + node_kind(n));
  return n.Scalar();
}

namespace {

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


}  // namespace

OptionValues validate_block(const Context& ctx, const YAML::Node& block, const OptionSchema& schema,
                            const std::string& what, const std::string& key_prefix,
                            const std::set<std::string>& skip) {
  OptionValues values;
  values.set_context(what, ctx.where(key_prefix, block));
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
      for (const auto& [name, what_now] : schema.retired)
        if (it == schema.end() && name == key)
          fail(ctx.where(full, node), what + ": '" + key + "' is no longer an option: " + what_now);
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
      values.mark_given(key, ctx.where(full, node));
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

namespace {


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

}  // namespace

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

}  // namespace pcdp::config_yaml

namespace pcdp::detail {
// For the simulator's scene YAML (sim/scene_config.cpp declares these).
OptionValues validate_yaml_block(const std::string& source, const YAML::Node& block, const OptionSchema& schema,
                                 const std::string& what, const std::string& key_prefix) {
  const config_yaml::Context ctx(source, ".");
  return config_yaml::validate_block(ctx, block, schema, what, key_prefix);
}
YAML::Node parse_yaml(const std::string& text, const std::string& source) { return config_yaml::load_yaml(text, source); }
std::string where(const std::string& source, const YAML::Node& n) {
  return config_yaml::Context(source, ".").where("", n);
}
}  // namespace pcdp::detail
