// Declared options: every configurable key (stage options and the sensor/mount/... blocks)
// is declared once, bound to the member of the Params struct it sets (Options<P> below); the
// member initialiser is the default. The same schema drives validation, `pcd_pipeline describe`
// and the generated docs, so they cannot drift.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
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

/// A rule across options ("range_min < range_max"), checked when the values are bound
/// (Options<P>::bind) and listed by describe and the generated docs.
struct OptionRule {
  std::string formula;            ///< as shown: "stable <= window"
  std::string why;                ///< one line
  std::vector<std::string> keys;  ///< the declared options the formula names, in its order
  /// The message when broken: "{key}" stands for the key's value; empty: "rule '<formula>' is
  /// broken: key = value unit, ... (<why>)".
  std::string message;
};

/// The options of a stage or block, in order, and the rules across them.
struct OptionSchema : std::vector<OptionSpec> {
  using std::vector<OptionSpec>::vector;
  std::vector<OptionRule> rules;
  /// Names that were options and are no longer, each with what became of it: a configuration
  /// that sets one is refused with that text rather than as an unknown option.
  std::vector<std::pair<std::string, std::string>> retired;
  /// nullptr when not declared.
  const OptionSpec* find(const std::string& name) const;
};

/// Validated values of one schema: every declared option has a value (given or default).
class OptionValues {
 public:
  bool has(const std::string& name) const { return values_.count(name) != 0; }
  void set(const std::string& name, OptionValue v) { values_[name] = std::move(v); }
  const std::map<std::string, OptionValue>& all() const { return values_; }
  /// Which options were given explicitly (not defaulted), and where ("p.yaml:12", "--set k=v").
  bool given(const std::string& name) const { return given_.count(name) != 0; }
  void mark_given(const std::string& name, std::string where = "") { given_[name] = std::move(where); }
  /// Where `name` was given; "" when it was not (or the place is unknown).
  std::string where_given(const std::string& name) const;
  /// How messages name the block ("sensor", "stage 'reg' (register)") and where it is.
  void set_context(std::string what, std::string where) {
    what_ = std::move(what);
    where_ = std::move(where);
  }
  const std::string& what() const { return what_; }
  const std::string& where() const { return where_; }

  double get_double(const std::string& name) const;
  std::int64_t get_int(const std::string& name) const;
  bool get_bool(const std::string& name) const;
  const std::string& get_string(const std::string& name) const;

 private:
  const OptionValue& at(const std::string& name) const;
  std::map<std::string, OptionValue> values_;
  std::map<std::string, std::string> given_;
  std::string what_, where_;
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

/// A multi-line table of a schema (name, type, default, bounds, unit, doc) and its rules, for
/// `describe`.
std::string describe_schema(const OptionSchema& schema);
/// The same as a Markdown table and a list of rules, for the generated reference (docs/stages.md).
std::string schema_markdown(const OptionSchema& schema);

// ---- declaring options bound to the members they set ----------------------------------------

/// Bounds of a number option (inclusive unless said).
struct Bounds {
  std::optional<double> min, max;
  bool min_exclusive = false, max_exclusive = false;
  Bounds& excluding_min() { return min_exclusive = true, *this; }
  Bounds& excluding_max() { return max_exclusive = true, *this; }
};
inline Bounds bounds(double lo, double hi) { return Bounds{lo, hi}; }
inline Bounds at_least(double lo) { return Bounds{lo, std::nullopt}; }
inline Bounds greater_than(double lo) { return Bounds{lo, std::nullopt, true, false}; }

namespace detail {
/// Throws ConfigError: `rule` of `schema` is broken by `values` (`detail`: what exactly, or "").
[[noreturn]] void throw_rule_broken(const OptionSchema& schema, const OptionRule& rule, const OptionValues& values,
                                    const std::string& detail);
/// The declared options a formula names (identifiers, dots allowed), in its order.
std::vector<std::string> formula_keys(const OptionSchema& schema, const std::string& formula);
}  // namespace detail

/// The options of a Params struct P, each declared once and bound to the member it sets (PDAL's
/// `args.add` is the model):
///
///   static const auto o = Options<OcclusionParams>()
///       .add("window", &OcclusionParams::window, bounds(1, 100), "returns", "how far to search")
///       .add("repair", &OcclusionParams::repair, "replace a false range ...")
///       .rule("stable <= window", [](const OcclusionParams& p) { return p.stable <= p.window; }, "why");
///   const OcclusionParams p = o.bind(stage_config.options);
///
/// The default of each option is its member's value in a default-constructed P. A member may be
/// named by a member pointer (also of a base of P) or by a function P& -> member& (for a part of
/// a member: [](MountParams& m) -> double& { return m.translation.x(); }). Numbers (double,
/// integers with bounds that fit the member's type), bool, std::string and enums (with their
/// choice names) are bound. Declaring a name twice is a logic error.
template <class P>
class Options {
  template <class Access>
  using Member = std::remove_reference_t<std::invoke_result_t<Access, P&>>;

 public:
  /// A number.
  template <class Access>
  Options& add(std::string name, Access access, Bounds b, std::string unit, std::string doc) {
    using M = Member<Access>;
    static_assert(std::is_arithmetic_v<M> && !std::is_same_v<M, bool>, "add(name, member, bounds, unit, doc) binds numbers");
    OptionSpec s;
    s.name = std::move(name);
    s.min = b.min;
    s.max = b.max;
    s.min_exclusive = b.min_exclusive;
    s.max_exclusive = b.max_exclusive;
    s.unit = std::move(unit);
    s.doc = std::move(doc);
    P d{};
    if constexpr (std::is_integral_v<M>) {
      // The bounds are checked before a value is bound: they must keep it within the member's type.
      if (!b.min || !b.max || *b.min < static_cast<double>(std::numeric_limits<M>::lowest()) ||
          *b.max > static_cast<double>(std::numeric_limits<M>::max()))
        throw std::logic_error("option '" + s.name + "': an integer option needs bounds within its member's type");
      s.type = OptionType::kInt;
      s.default_value = static_cast<std::int64_t>(std::invoke(access, d));
      const std::string n = s.name;
      return declare(std::move(s), [n, access](const OptionValues& v, P& p) {
        std::invoke(access, p) = static_cast<M>(v.get_int(n));
      });
    } else {
      s.type = OptionType::kDouble;
      s.default_value = static_cast<double>(std::invoke(access, d));
      const std::string n = s.name;
      return declare(std::move(s), [n, access](const OptionValues& v, P& p) {
        std::invoke(access, p) = static_cast<M>(v.get_double(n));
      });
    }
  }

  /// A bool or a string.
  template <class Access>
  Options& add(std::string name, Access access, std::string doc) {
    using M = Member<Access>;
    static_assert(std::is_same_v<M, bool> || std::is_same_v<M, std::string>,
                  "add(name, member, doc) binds bool and std::string members");
    OptionSpec s;
    s.name = std::move(name);
    s.type = std::is_same_v<M, bool> ? OptionType::kBool : OptionType::kString;
    s.doc = std::move(doc);
    P d{};
    s.default_value = std::invoke(access, d);
    const std::string n = s.name;
    return declare(std::move(s), [n, access](const OptionValues& v, P& p) {
      if constexpr (std::is_same_v<M, bool>)
        std::invoke(access, p) = v.get_bool(n);
      else
        std::invoke(access, p) = v.get_string(n);
    });
  }

  /// An enum, written as one of the choice names.
  template <class Access>
  Options& add(std::string name, Access access, std::vector<std::pair<std::string, Member<Access>>> choices,
               std::string doc) {
    using M = Member<Access>;
    static_assert(std::is_enum_v<M>, "add(name, member, choices, doc) binds enum members");
    OptionSpec s;
    s.name = std::move(name);
    s.type = OptionType::kEnum;
    s.doc = std::move(doc);
    P d{};
    const M def = std::invoke(access, d);
    bool found = false;
    for (const auto& [text, value] : choices) {
      s.choices.push_back(text);
      if (value == def) s.default_value = text, found = true;
    }
    if (!found) throw std::logic_error("option '" + s.name + "': the member's default is none of the choices");
    const std::string n = s.name;
    return declare(std::move(s), [n, access, choices](const OptionValues& v, P& p) {
      const std::string& text = v.get_string(n);
      for (const auto& c : choices)
        if (c.first == text) std::invoke(access, p) = c.second;
    });
  }

  /// A name that was an option and is no longer; `what_now` says what became of it ("fixed at
  /// 1.5: ..."). Naming a declared or already retired option is a logic error.
  Options& retire(std::string name, std::string what_now) {
    if (schema_.find(name)) throw std::logic_error("option '" + name + "' is declared and retired");
    for (const auto& r : schema_.retired)
      if (r.first == name) throw std::logic_error("option '" + name + "' is retired twice");
    schema_.retired.emplace_back(std::move(name), std::move(what_now));
    return *this;
  }

  /// A rule across options: `check(const P&)` returns true when kept (or an optional string:
  /// nullopt when kept, else what is wrong, appended to the message in parentheses). `formula`
  /// names the options it reads; `message`, if given, is the error text with "{key}" standing
  /// for a value (see OptionRule).
  template <class Check>
  Options& rule(std::string formula, Check check, std::string why, std::string message = "") {
    OptionRule r;
    r.keys = detail::formula_keys(schema_, formula);
    if (r.keys.empty()) throw std::logic_error("rule '" + formula + "' names no declared option");
    r.formula = std::move(formula);
    r.why = std::move(why);
    r.message = std::move(message);
    const std::size_t index = schema_.rules.size();
    schema_.rules.push_back(std::move(r));
    checks_.push_back([index, check](const OptionSchema& schema, const P& p, const OptionValues& v) {
      std::optional<std::string> broken;
      if constexpr (std::is_same_v<std::invoke_result_t<Check, const P&>, bool>) {
        if (!check(p)) broken = std::string();
      } else {
        broken = check(p);
      }
      if (broken) detail::throw_rule_broken(schema, schema.rules[index], v, *broken);
    });
    return *this;
  }

  const OptionSchema& schema() const { return schema_; }

  /// A P with every declared member set from `values` (a member whose option has no value keeps
  /// its default), after checking the rules (ConfigError naming where, the block, keys, values
  /// and rule).
  P bind(const OptionValues& values) const {
    P p{};
    for (const auto& set : setters_) set(values, p);
    for (const auto& check : checks_) check(schema_, p, values);
    return p;
  }

 private:
  using Setter = std::function<void(const OptionValues&, P&)>;

  Options& declare(OptionSpec spec, Setter set) {
    if (schema_.find(spec.name)) throw std::logic_error("option '" + spec.name + "' is declared twice");
    for (const auto& r : schema_.retired)
      if (r.first == spec.name) throw std::logic_error("option '" + spec.name + "' is retired and declared");
    const std::string n = spec.name;
    schema_.push_back(std::move(spec));
    setters_.push_back([n, set](const OptionValues& v, P& p) {
      if (v.has(n)) set(v, p);
    });
    return *this;
  }

  OptionSchema schema_;
  std::vector<Setter> setters_;
  std::vector<std::function<void(const OptionSchema&, const P&, const OptionValues&)>> checks_;
};

}  // namespace pcdp
