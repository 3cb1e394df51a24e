#include "pcdp/pipeline/options.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "pcdp/core/errors.hpp"

namespace pcdp {

const char* option_type_name(OptionType t) {
  switch (t) {
    case OptionType::kBool: return "bool";
    case OptionType::kInt: return "int";
    case OptionType::kDouble: return "double";
    case OptionType::kString: return "string";
    case OptionType::kEnum: return "enum";
  }
  return "?";
}

std::string format_value(const OptionValue& v) {
  if (std::holds_alternative<bool>(v)) return std::get<bool>(v) ? "true" : "false";
  if (std::holds_alternative<std::int64_t>(v)) return std::to_string(std::get<std::int64_t>(v));
  if (std::holds_alternative<double>(v)) return format_number(std::get<double>(v));
  return std::get<std::string>(v);
}

std::string OptionSpec::bounds_text() const {
  if (type == OptionType::kEnum) {
    std::string s;
    for (std::size_t i = 0; i < choices.size(); ++i) s += (i ? "|" : "") + choices[i];
    return s;
  }
  if (type != OptionType::kInt && type != OptionType::kDouble) return "";
  if (!min && !max) return "";
  std::string s = min ? (min_exclusive ? "(" : "[") + format_number(*min) : "(-inf";
  s += ", ";
  s += max ? format_number(*max) + (max_exclusive ? ")" : "]") : "inf)";
  return s;
}

OptionSpec opt_double(std::string name, double def, std::optional<double> min,
                      std::optional<double> max, std::string unit, std::string doc) {
  OptionSpec s;
  s.name = std::move(name);
  s.type = OptionType::kDouble;
  s.default_value = def;
  s.min = min;
  s.max = max;
  s.unit = std::move(unit);
  s.doc = std::move(doc);
  return s;
}

OptionSpec opt_int(std::string name, std::int64_t def, std::optional<double> min,
                   std::optional<double> max, std::string unit, std::string doc) {
  OptionSpec s = opt_double(std::move(name), 0.0, min, max, std::move(unit), std::move(doc));
  s.type = OptionType::kInt;
  s.default_value = def;
  return s;
}

OptionSpec opt_bool(std::string name, bool def, std::string doc) {
  OptionSpec s;
  s.name = std::move(name);
  s.type = OptionType::kBool;
  s.default_value = def;
  s.doc = std::move(doc);
  return s;
}

OptionSpec opt_enum(std::string name, std::string def, std::vector<std::string> choices,
                    std::string doc) {
  OptionSpec s;
  s.name = std::move(name);
  s.type = OptionType::kEnum;
  s.default_value = std::move(def);
  s.choices = std::move(choices);
  s.doc = std::move(doc);
  return s;
}

OptionSpec opt_string(std::string name, std::string def, std::string doc) {
  OptionSpec s;
  s.name = std::move(name);
  s.type = OptionType::kString;
  s.default_value = std::move(def);
  s.doc = std::move(doc);
  return s;
}

const OptionSpec* OptionSchema::find(const std::string& name) const {
  for (const auto& s : *this)
    if (s.name == name) return &s;
  return nullptr;
}

std::string OptionValues::where_given(const std::string& name) const {
  auto it = given_.find(name);
  return it == given_.end() ? std::string() : it->second;
}

const OptionValue& OptionValues::at(const std::string& name) const {
  auto it = values_.find(name);
  if (it == values_.end()) throw std::logic_error("option '" + name + "' was not declared");
  return it->second;
}

double OptionValues::get_double(const std::string& name) const {
  const auto& v = at(name);
  if (std::holds_alternative<std::int64_t>(v)) return static_cast<double>(std::get<std::int64_t>(v));
  return std::get<double>(v);
}
std::int64_t OptionValues::get_int(const std::string& name) const {
  return std::get<std::int64_t>(at(name));
}
bool OptionValues::get_bool(const std::string& name) const { return std::get<bool>(at(name)); }
const std::string& OptionValues::get_string(const std::string& name) const {
  return std::get<std::string>(at(name));
}

namespace {
std::optional<std::string> check_bounds(const OptionSpec& spec, double v) {
  const std::string unit = spec.unit.empty() ? "" : " " + spec.unit;
  if (spec.min && (spec.min_exclusive ? v <= *spec.min : v < *spec.min))
    return std::string("must be ") + (spec.min_exclusive ? "greater than " : "at least ") +
           format_number(*spec.min) + unit + " (allowed " + spec.bounds_text() + ")";
  if (spec.max && (spec.max_exclusive ? v >= *spec.max : v > *spec.max))
    return std::string("must be ") + (spec.max_exclusive ? "less than " : "at most ") +
           format_number(*spec.max) + unit + " (allowed " + spec.bounds_text() + ")";
  return std::nullopt;
}
}  // namespace

std::optional<std::string> parse_option_value(const OptionSpec& spec, const std::string& text,
                                              OptionValue& out) {
  switch (spec.type) {
    case OptionType::kBool:
      if (text == "true") { out = true; return std::nullopt; }
      if (text == "false") { out = false; return std::nullopt; }
      return std::string("must be true or false");
    case OptionType::kInt: {
      errno = 0;
      char* end = nullptr;
      const long long v = std::strtoll(text.c_str(), &end, 10);
      if (text.empty() || *end != '\0' || errno == ERANGE || text.find_first_not_of("+-0123456789") != std::string::npos)
        return std::string("must be an integer");
      if (auto e = check_bounds(spec, static_cast<double>(v))) return e;
      out = static_cast<std::int64_t>(v);
      return std::nullopt;
    }
    case OptionType::kDouble: {
      errno = 0;
      char* end = nullptr;
      const double v = std::strtod(text.c_str(), &end);
      // Decimal only: strtod would also take leading blanks, hexadecimal and "nan"/"inf".
      if (text.empty() || *end != '\0') return std::string("must be a number");
      if (!std::isfinite(v)) return std::string("must be a finite number");
      // ERANGE with a finite non-zero value is an underflow to a subnormal (1e-320): that number.
      // Underflow to 0 (1e-400) would silently turn an option off: refused.
      if (text.find_first_not_of("+-.0123456789eE") != std::string::npos) return std::string("must be a number");
      if (errno == ERANGE && v == 0.0) return std::string("is too small for a double (it would read as 0)");
      if (auto e = check_bounds(spec, v)) return e;
      out = v;
      return std::nullopt;
    }
    case OptionType::kEnum:
      for (const auto& c : spec.choices)
        if (c == text) { out = text; return std::nullopt; }
      return "must be one of " + spec.bounds_text();
    case OptionType::kString:
      out = text;
      return std::nullopt;
  }
  return std::string("has an unknown type");
}

std::optional<std::size_t> invalid_utf8_offset(const std::string& text) {
  const auto* s = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  for (std::size_t i = 0; i < n;) {
    const unsigned c = s[i];
    if (c < 0x80) {
      ++i;
      continue;
    }
    std::size_t len = 0;
    unsigned lo = 0x80, hi = 0xBF;  // the allowed range of the second byte
    if (c >= 0xC2 && c <= 0xDF) len = 2;
    else if (c == 0xE0) len = 3, lo = 0xA0;
    else if (c == 0xED) len = 3, hi = 0x9F;  // no surrogates
    else if (c >= 0xE1 && c <= 0xEF) len = 3;
    else if (c == 0xF0) len = 4, lo = 0x90;
    else if (c >= 0xF1 && c <= 0xF3) len = 4;
    else if (c == 0xF4) len = 4, hi = 0x8F;  // not above U+10FFFF
    else return i;
    if (i + len > n) return i;
    if (s[i + 1] < lo || s[i + 1] > hi) return i;
    for (std::size_t k = 2; k < len; ++k)
      if (s[i + k] < 0x80 || s[i + k] > 0xBF) return i;
    i += len;
  }
  return std::nullopt;
}

std::optional<std::string> parse_number_list(const std::string& text, std::size_t count, std::vector<double>& out) {
  std::vector<std::string> cells(1);
  for (char ch : text) {
    if (ch == ',') cells.emplace_back();
    else cells.back() += ch;
  }
  if (cells.size() != count)
    return "has " + std::to_string(cells.size()) + " comma-separated value" + (cells.size() == 1 ? "" : "s") +
           ", needs " + std::to_string(count);
  std::vector<double> v;
  for (std::string c : cells) {
    const auto b = c.find_first_not_of(" \t"), e = c.find_last_not_of(" \t");
    c = b == std::string::npos ? "" : c.substr(b, e - b + 1);
    errno = 0;
    char* end = nullptr;
    const double x = std::strtod(c.c_str(), &end);
    if (c.empty() || *end != '\0' || !std::isfinite(x) || (errno == ERANGE && x == 0.0) ||  // an underflow to 0 is refused
        c.find_first_not_of("+-.0123456789eE") != std::string::npos)
      return "'" + c + "' is not a finite number";
    v.push_back(x);
  }
  out = std::move(v);
  return std::nullopt;
}

namespace detail {

std::vector<std::string> formula_keys(const OptionSchema& schema, const std::string& formula) {
  std::vector<std::string> keys;
  const auto word = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.'; };
  for (std::size_t i = 0; i < formula.size();) {
    if (!word(formula[i])) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < formula.size() && word(formula[j])) ++j;
    const std::string w = formula.substr(i, j - i);
    if (schema.find(w) && std::find(keys.begin(), keys.end(), w) == keys.end()) keys.push_back(w);
    i = j;
  }
  return keys;
}

void throw_rule_broken(const OptionSchema& schema, const OptionRule& rule, const OptionValues& values,
                       const std::string& detail) {
  const auto value_of = [&](const std::string& key) {
    if (values.has(key)) return values.all().at(key);
    const OptionSpec* s = schema.find(key);
    return s ? s->default_value : OptionValue(std::string("?"));
  };
  // Where: the last of the rule's keys that was given (the one that broke it, most likely).
  std::string where = values.where();
  for (const auto& k : rule.keys)
    if (values.given(k) && !values.where_given(k).empty()) where = values.where_given(k);
  std::string text;
  if (rule.message.empty()) {
    text = "rule '" + rule.formula + "' is broken: ";
    for (std::size_t i = 0; i < rule.keys.size(); ++i) {
      const OptionSpec* s = schema.find(rule.keys[i]);
      text += (i ? ", " : "") + rule.keys[i] + " = " + format_value(value_of(rule.keys[i])) +
              (s && !s->unit.empty() ? " " + s->unit : "");
    }
    if (!rule.why.empty()) text += " (" + rule.why + ")";
  } else {
    for (std::size_t i = 0; i < rule.message.size(); ++i) {
      const std::size_t close = rule.message[i] == '{' ? rule.message.find('}', i) : std::string::npos;
      const std::string key = close == std::string::npos ? "" : rule.message.substr(i + 1, close - i - 1);
      if (!key.empty() && schema.find(key)) {
        text += format_value(value_of(key));
        i = close;
      } else {
        text += rule.message[i];
      }
    }
  }
  if (!detail.empty()) text += " (" + detail + ")";
  std::string msg = where.empty() ? "" : where + ": ";
  if (!values.what().empty()) msg += values.what() + ": ";
  throw ConfigError(msg + text);
}

}  // namespace detail

std::string describe_schema(const OptionSchema& schema) {
  std::ostringstream os;
  const auto default_text = [](const OptionSpec& s) {
    std::string def = s.required ? "(required)" : format_value(s.default_value);
    return def.empty() ? std::string("\"\"") : def;
  };
  // Each column as wide as its widest entry, plus two spaces: wide bounds never run into the unit.
  std::size_t w = 6, wd = 7, wb = 6, wu = 4;
  for (const auto& s : schema) {
    w = std::max(w, s.name.size());
    wd = std::max(wd, default_text(s).size());
    wb = std::max(wb, s.bounds_text().size());
    wu = std::max(wu, s.unit.size());
  }
  const auto col = [](std::size_t n) { return std::setw(static_cast<int>(n) + 2); };
  os << std::left << col(w) << "option" << std::setw(8) << "type" << col(wd) << "default" << col(wb) << "bounds"
     << col(wu) << "unit" << "description\n";
  for (const auto& s : schema)
    os << std::left << col(w) << s.name << std::setw(8) << option_type_name(s.type) << col(wd) << default_text(s)
       << col(wb) << s.bounds_text() << col(wu) << (s.unit.empty() ? "-" : s.unit) << s.doc << "\n";
  if (!schema.rules.empty()) {
    os << "\nrules\n";
    for (const auto& r : schema.rules) os << "  " << r.formula << (r.why.empty() ? "" : ": " + r.why) << "\n";
  }
  if (!schema.retired.empty()) {
    os << "\nrefused keys (a configuration that sets one fails, naming what to do instead)\n";
    for (const auto& [name, what_now] : schema.retired) os << "  " << name << ": " << what_now << "\n";
  }
  return os.str();
}

}  // namespace pcdp

namespace pcdp {

std::string schema_markdown(const OptionSchema& schema) {
  std::ostringstream os;
  os << "| option | type | default | bounds | unit | description |\n|---|---|---|---|---|---|\n";
  for (const auto& s : schema) {
    std::string def = s.required ? "(required)" : format_value(s.default_value);
    if (def.empty()) def = "\"\"";
    std::string b = s.bounds_text();
    for (std::size_t p = b.find('|'); p != std::string::npos; p = b.find('|', p + 2)) b.replace(p, 1, "\\|");
    os << "| `" << s.name << "` | " << option_type_name(s.type) << " | `" << def << "` | " << (b.empty() ? "" : "`" + b + "`")
       << " | " << (s.unit.empty() ? "" : s.unit) << " | " << s.doc << " |\n";
  }
  if (!schema.rules.empty()) {
    os << "\nRules:\n\n";
    for (const auto& r : schema.rules) os << "- `" << r.formula << "`" << (r.why.empty() ? "" : ": " + r.why) << "\n";
  }
  if (!schema.retired.empty()) {
    os << "\nRefused keys (a configuration that sets one fails, naming what to do instead):\n\n";
    for (const auto& [name, what_now] : schema.retired) os << "- `" << name << "`: " << what_now << "\n";
  }
  return os.str();
}

}  // namespace pcdp
