// Builds PipelineConfig from pipeline YAML: top-level keys, input and output, the fixed blocks
// (declared in config_blocks.cpp) and the stage list. Reading the YAML itself (strict checks,
// --set, block validation) is config_yaml.cpp; nothing else parses YAML.
#include "pcdp/pipeline/config.hpp"

#include <glob.h>
#include <sys/stat.h>
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
#include "pcdp/io/paths.hpp"
#include "pcdp/pipeline/stage.hpp"
#include "pipeline/config_yaml.hpp"

namespace fs = std::filesystem;

namespace pcdp {

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

using config_yaml::apply_override;
using config_yaml::Context;
using config_yaml::fail;
using config_yaml::instance_name;
using config_yaml::load_yaml;
using config_yaml::node_kind;
using config_yaml::scalar_of;
using config_yaml::validate_block;

const std::vector<std::string> kTopKeys = {"description", "rpy_order",  "input",  "output_dir",        "mount",
                                           "sensor",      "pose_sigma", "stages", "allow_empty_output", "crs"};
const std::vector<std::string> kInputKeys = {"scans", "poses"};

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
      std::string canon = io::resolved_path(f).string();
      if (canon.empty()) canon = f;  // no working directory: compared as given
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
    cfg.allow_empty_output = top_level_options().bind(v).allow_empty_output;  // crs: normalized below
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
  cfg.mount = mount_options().bind(mount);
  const OptionValues sensor = validate_block(ctx, root["sensor"], sensor_schema(), "sensor", "sensor");
  cfg.sensor = sensor_options().bind(sensor);
  const OptionValues ps = validate_block(ctx, root["pose_sigma"], pose_sigma_schema(), "pose_sigma", "pose_sigma");
  cfg.pose_sigma = pose_sigma_options().bind(ps);
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

namespace {
/// The first line (1-based) whose quoted value is not closed on it, or 0. YAML lets a quoted
/// scalar run over several lines, so a quote left open swallows the keys below it and the error
/// is about them ("required key 'stages' is missing"); a pipeline file never needs one.
std::size_t open_quote_line(const std::string& yaml) {
  std::size_t line = 1;
  int flow = 0;                                  // depth of [ ] and { } outside quotes
  std::size_t block_indent = std::string::npos;  // inside a | or > block scalar: its key's indentation
  for (std::size_t i = 0; i < yaml.size(); i = std::min(yaml.find('\n', i), yaml.size()) + 1, ++line) {
    const std::size_t eol = std::min(yaml.find('\n', i), yaml.size());
    const std::size_t first = yaml.find_first_not_of(' ', i);
    const std::size_t indent = (first == std::string::npos ? eol : std::min(first, eol)) - i;
    if (block_indent != std::string::npos) {
      if (first == std::string::npos || first >= eol || yaml[first] == '\r' || indent > block_indent) continue;  // the block's text
      block_indent = std::string::npos;
    }
    // The line's leading sequence indicators ("- - "): where its first key or value starts.
    std::size_t lead = i + indent;
    while (lead + 1 < eol && yaml[lead] == '-' && yaml[lead + 1] == ' ') {
      lead += 2;
      while (lead < eol && yaml[lead] == ' ') ++lead;
    }
    char open = 0;
    std::size_t last = std::string::npos;  // the last character outside quotes and comments
    for (std::size_t k = i; k < eol; ++k) {
      const char c = yaml[k];
      if (open == '"' && c == '\\') {
        ++k;  // an escape inside double quotes
      } else if (open != 0) {
        if (c != open) continue;
        if (open == '\'' && k + 1 < eol && yaml[k + 1] == '\'') ++k;  // '' inside single quotes: a quote
        else open = 0;
      } else if (c == '#' && (k == i || yaml[k - 1] == ' ' || yaml[k - 1] == '\t')) {
        break;  // a comment
      } else if (c == '"' || c == '\'') {
        // A quote opens a scalar only where a value starts: the line's start, after ': ', after a
        // sequence's leading '- ', or after '[', '{' or ',' inside a flow collection.
        std::size_t b = k;
        while (b > i && yaml[b - 1] == ' ') --b;
        const char before = b > i ? yaml[b - 1] : 0;
        const bool starts = before == 0 || (before == ':' && b < k) || k == lead ||  // after the leading "- "
                            (flow > 0 && (before == '[' || before == '{' || before == ','));
        if (starts) open = c;
        else last = k;
      } else {
        if (c == '[' || c == '{') ++flow;
        if ((c == ']' || c == '}') && flow > 0) --flow;
        if (c != ' ' && c != '\t' && c != '\r') last = k;
      }
    }
    if (open != 0) return line;
    // "key: |" or "key: >-": the lines below, indented deeper, are the block's text.
    if (last != std::string::npos) {
      std::size_t k = last;
      while (k > i && (yaml[k] == '-' || yaml[k] == '+' || (yaml[k] >= '0' && yaml[k] <= '9'))) --k;
      if ((yaml[k] == '|' || yaml[k] == '>') && (k == i || yaml[k - 1] == ' ')) block_indent = lead - i;  // the key's column
    }
  }
  return 0;
}
}  // namespace

PipelineConfig load_pipeline_from_string(const std::string& yaml, const std::string& source_name,
                                         const std::string& base_dir, const LoadOptions& opts) {
  Context ctx(source_name, base_dir);
  try {
    YAML::Node root = load_yaml(yaml, source_name);
    return build(root, ctx, opts);
  } catch (const ConfigError& e) {
    if (const std::size_t l = open_quote_line(yaml))
      throw ConfigError(std::string(e.what()) + " (note: " + source_name + ":" + std::to_string(l) +
                        " opens a quoted value that the line does not close, so it runs on over the lines below)");
    throw;
  }
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