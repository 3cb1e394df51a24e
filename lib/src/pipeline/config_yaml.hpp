// Internal: reading pipeline YAML (config_yaml.cpp): the strict event-stream check, the "where"
// of a key (file:line or --set), --set overrides written into the tree, and the validation of a
// block against its option schema. config.cpp builds PipelineConfig on these.
#pragma once

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "pcdp/core/errors.hpp"
#include "pcdp/pipeline/config.hpp"
#include "pcdp/pipeline/options.hpp"

namespace pcdp::config_yaml {

/// "a list", "a mapping", "empty", "a value": how messages name what a node is.
std::string node_kind(const YAML::Node& n);

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
    if (p.empty() || std::filesystem::path(p).is_absolute() || overridden(key)) return p;
    return (std::filesystem::path(base_) / p).lexically_normal().string();
  }

  const std::string& source() const { return source_; }

 private:
  std::string source_;
  std::string base_;
  std::map<std::string, std::string> overrides_;
};

[[noreturn]] void fail(const std::string& where, const std::string& msg);

/// The scalar text of `n`, or ConfigError "<what> '<key>' must be a single value".
std::string scalar_of(const Context& ctx, const std::string& key, const YAML::Node& n, const std::string& what);

/// Validates a block (a mapping) against a schema. `what` names it in messages ("sensor",
/// "stage 'reg' (register)"); `key_prefix` is the dotted prefix used by --set. The values know
/// `what`, the block's place and where each given key was (for the rules checked at bind).
OptionValues validate_block(const Context& ctx, const YAML::Node& block, const OptionSchema& schema,
                            const std::string& what, const std::string& key_prefix,
                            const std::set<std::string>& skip = {});

/// Parses YAML text after the strict check (duplicate keys, second documents, depth, UTF-8);
/// throws ConfigError naming the source, line and rule.
YAML::Node load_yaml(const std::string& text, const std::string& source);

/// A stage entry's instance name: its `name`, else its `type`, else "".
std::string instance_name(const YAML::Node& st);

/// Writes a --set override into the YAML tree (validated afterwards like any other key).
void apply_override(YAML::Node root, const Override& ov, Context& ctx);

}  // namespace pcdp::config_yaml
