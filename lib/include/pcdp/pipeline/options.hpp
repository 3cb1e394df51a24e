// Declared options: every configurable key (stage options and the sensor/mount/... blocks)
// is declared once as an OptionSpec. The same schema drives validation, `pcd_pipeline describe`
// and the generated docs, so they cannot drift.
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace pcdp {

enum class OptionType { kBool, kInt, kDouble, kString, kEnum };
const char* option_type_name(OptionType t);

using OptionValue = std::variant<bool, std::int64_t, double, std::string>;
std::string format_value(const OptionValue& v);

struct OptionSpec {
  std::string name;
  OptionType type = OptionType::kDouble;
  OptionValue default_value = 0.0;
  bool required = false;
  std::optional<double> min;  ///< inclusive lower bound (numbers)
  std::optional<double> max;  ///< inclusive upper bound (numbers)
  bool min_exclusive = false;
  bool max_exclusive = false;
  std::string unit;                  ///< "m", "rad", "s", "" ...
  std::string doc;                   ///< one line
  std::vector<std::string> choices;  ///< kEnum only

  /// "[0, 30]", "(0, inf)", "fixed|mirror", "" — human-readable bounds for describe/docs.
  std::string bounds_text() const;
};

/// Fluent helpers so schemas read like tables.
OptionSpec opt_double(std::string name, double def, std::optional<double> min,
                      std::optional<double> max, std::string unit, std::string doc);
OptionSpec opt_int(std::string name, std::int64_t def, std::optional<double> min,
                   std::optional<double> max, std::string unit, std::string doc);
OptionSpec opt_bool(std::string name, bool def, std::string doc);
OptionSpec opt_enum(std::string name, std::string def, std::vector<std::string> choices,
                    std::string doc);
OptionSpec opt_string(std::string name, std::string def, std::string doc);

using OptionSchema = std::vector<OptionSpec>;

/// Validated values of one schema: every declared option has a value (given or default).
class OptionValues {
 public:
  bool has(const std::string& name) const { return values_.count(name) != 0; }
  void set(const std::string& name, OptionValue v) { values_[name] = std::move(v); }
  const std::map<std::string, OptionValue>& all() const { return values_; }
  /// Which options were given explicitly (not defaulted).
  bool given(const std::string& name) const { return given_.count(name) != 0; }
  void mark_given(const std::string& name) { given_[name] = true; }

  double get_double(const std::string& name) const;
  std::int64_t get_int(const std::string& name) const;
  bool get_bool(const std::string& name) const;
  const std::string& get_string(const std::string& name) const;

 private:
  const OptionValue& at(const std::string& name) const;
  std::map<std::string, OptionValue> values_;
  std::map<std::string, bool> given_;
};

/// Parses `text` as a value of `spec` and checks its bounds. On failure returns the rule
/// broken (e.g. "must be a number", "is below the minimum 0 m"); on success sets `out`.
std::optional<std::string> parse_option_value(const OptionSpec& spec, const std::string& text,
                                              OptionValue& out);

/// The byte offset of the first byte of `text` that is not valid UTF-8 (overlong forms,
/// surrogates and code points above U+10FFFF count as invalid), or nullopt when all of it is.
std::optional<std::size_t> invalid_utf8_offset(const std::string& text);

/// Parses exactly `count` comma-separated finite numbers ("-10,-10,20,10"), nothing before,
/// between or after them but optional blanks around each. On failure returns the rule broken
/// ("has 5 values, needs 4", "'10junk' is not a number"); on success fills `out`.
std::optional<std::string> parse_number_list(const std::string& text, std::size_t count, std::vector<double>& out);

/// A multi-line table of a schema (name, type, default, bounds, unit, doc), for `describe`.
std::string describe_schema(const OptionSchema& schema);
/// The same as a Markdown table, for the generated reference (docs/stages.md).
std::string schema_markdown(const OptionSchema& schema);

}  // namespace pcdp
