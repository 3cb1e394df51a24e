#include <gtest/gtest.h>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/pipeline/options.hpp"
#include "pcdp/stages/register.hpp"

using namespace pcdp;

TEST(Options, ParsesTypesAndChecksBounds) {
  OptionValue v;
  const OptionSpec d = opt_double("d", 1.0, 0.0, 10.0, "m", "doc");
  EXPECT_FALSE(parse_option_value(d, "2.5", v));
  EXPECT_DOUBLE_EQ(std::get<double>(v), 2.5);
  EXPECT_NE(parse_option_value(d, "-1", v)->find("at least 0 m"), std::string::npos);
  EXPECT_NE(parse_option_value(d, "11", v)->find("at most 10 m"), std::string::npos);
  EXPECT_NE(parse_option_value(d, "abc", v)->find("must be a number"), std::string::npos);
  EXPECT_NE(parse_option_value(d, "nan", v)->find("finite"), std::string::npos);
  EXPECT_NE(parse_option_value(d, "1.0m", v)->find("must be a number"), std::string::npos);

  OptionSpec ex = d;
  ex.min_exclusive = true;
  EXPECT_NE(parse_option_value(ex, "0", v)->find("greater than 0"), std::string::npos);
  EXPECT_EQ(ex.bounds_text(), "(0, 10]");

  const OptionSpec i = opt_int("i", 3, 1.0, std::nullopt, "", "doc");
  EXPECT_FALSE(parse_option_value(i, "7", v));
  EXPECT_EQ(std::get<std::int64_t>(v), 7);
  EXPECT_TRUE(parse_option_value(i, "7.5", v));
  EXPECT_TRUE(parse_option_value(i, "0", v));
  EXPECT_EQ(i.bounds_text(), "[1, inf)");

  const OptionSpec b = opt_bool("b", true, "doc");
  EXPECT_FALSE(parse_option_value(b, "false", v));
  EXPECT_FALSE(std::get<bool>(v));
  EXPECT_NE(parse_option_value(b, "maybe", v)->find("true or false"), std::string::npos);

  const OptionSpec e = opt_enum("e", "fixed", {"fixed", "mirror"}, "doc");
  EXPECT_FALSE(parse_option_value(e, "mirror", v));
  EXPECT_NE(parse_option_value(e, "coaxial", v)->find("fixed|mirror"), std::string::npos);
}

TEST(Options, DescribeListsEveryOptionWithDefaultBoundsAndUnit) {
  const std::string text = describe_schema(register_schema());
  for (const auto& s : register_schema()) {
    EXPECT_NE(text.find(s.name), std::string::npos) << s.name;
    EXPECT_NE(text.find(s.doc), std::string::npos) << s.name;
  }
  EXPECT_NE(text.find("[0, inf)"), std::string::npos);
  const std::string sensor = describe_schema(sensor_schema());
  EXPECT_NE(sensor.find("range_calibration.k"), std::string::npos);
  EXPECT_NE(sensor.find("fixed|mirror"), std::string::npos);
}

TEST(Options, SuggestsNearestName) {
  EXPECT_EQ(nearest_name("skew_corection", {"skew_correction", "max_pose_gap"}), "skew_correction");
  EXPECT_EQ(nearest_name("regster", {"register"}), "register");
  EXPECT_EQ(nearest_name("completely_else", {"register"}), "");
  EXPECT_EQ(edit_distance("kitten", "sitting"), 3u);
}

// ---- Options<P>: each option declared once, bound to the member it sets ---------------------

namespace {
enum class Mode { kFast, kSafe };
struct BinderParams {
  double lo = 0.25;
  double hi = 2.0;
  int count = 2;
  std::uint32_t support = 3;
  bool flag = true;
  std::string label = "x";
  Mode mode = Mode::kSafe;
  struct {
    double a = 1.5;
  } inner;
};

Options<BinderParams> binder_options() {
  using P = BinderParams;
  Options<P> o;
  o.add("lo", &P::lo, bounds(0, 10), "m", "lower")
      .add("hi", &P::hi, greater_than(0), "m", "upper")
      .add("count", &P::count, bounds(1, 100), "", "a count")
      .add("support", &P::support, bounds(1, 1000), "points", "support")
      .add("flag", &P::flag, "a flag")
      .add("label", &P::label, "a label")
      .add("mode", &P::mode, {{"fast", Mode::kFast}, {"safe", Mode::kSafe}}, "a mode")
      .add("inner.a", [](P& p) -> double& { return p.inner.a; }, bounds(0, 5), "", "nested")
      .rule("lo < hi", [](const P& p) { return p.lo < p.hi; }, "an interval")
      .rule("count <= support", [](const P& p) { return p.count <= static_cast<int>(p.support); }, "why",
            "option 'count' = {count} must not exceed 'support' = {support}");
  return o;
}

/// The values validate_block would produce: every option, given ones marked with their place.
OptionValues values_of(const OptionSchema& schema, const std::map<std::string, OptionValue>& given) {
  OptionValues v;
  v.set_context("stage 'b' (binder)", "p.yaml:3");
  for (const auto& s : schema) v.set(s.name, s.default_value);
  int line = 4;
  for (const auto& [k, val] : given) {
    v.set(k, val);
    v.mark_given(k, "p.yaml:" + std::to_string(line++));
  }
  return v;
}

std::string rule_error(const Options<BinderParams>& o, const std::map<std::string, OptionValue>& given) {
  try {
    o.bind(values_of(o.schema(), given));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}
}  // namespace

TEST(OptionsBinder, TheDefaultComesFromTheMember) {
  const auto o = binder_options();
  const OptionSchema& s = o.schema();
  ASSERT_EQ(s.size(), 8u);
  EXPECT_EQ(std::get<double>(s.find("lo")->default_value), 0.25);
  EXPECT_EQ(s.find("count")->type, OptionType::kInt);
  EXPECT_EQ(std::get<std::int64_t>(s.find("count")->default_value), 2);
  EXPECT_EQ(std::get<std::int64_t>(s.find("support")->default_value), 3);
  EXPECT_EQ(std::get<bool>(s.find("flag")->default_value), true);
  EXPECT_EQ(std::get<std::string>(s.find("label")->default_value), "x");
  EXPECT_EQ(std::get<std::string>(s.find("mode")->default_value), "safe");
  EXPECT_EQ(s.find("mode")->bounds_text(), "fast|safe");
  EXPECT_EQ(std::get<double>(s.find("inner.a")->default_value), 1.5);
  EXPECT_EQ(s.find("hi")->bounds_text(), "(0, inf)");
  // The shipped blocks and stages: a default is the member initialiser.
  EXPECT_EQ(std::get<double>(sensor_schema().find("range_max")->default_value), SensorParams{}.range_max);
  EXPECT_EQ(std::get<double>(sensor_schema().find("range_calibration.k")->default_value), SensorParams{}.range_k);
  EXPECT_EQ(sensor_schema().find("range_calibration.k")->bounds_text(), "(0.5, 2]");
  EXPECT_EQ(std::get<std::int64_t>(register_schema().find("blind_lines")->default_value), RegisterParams{}.blind_lines);
}

TEST(OptionsBinder, BindFillsEveryMemberFromTheValues) {
  const auto o = binder_options();
  const BinderParams d = o.bind(values_of(o.schema(), {}));
  EXPECT_EQ(d.lo, 0.25);
  EXPECT_EQ(d.mode, Mode::kSafe);
  const BinderParams p = o.bind(values_of(o.schema(), {{"lo", 1.0},
                                                       {"count", std::int64_t{2}},
                                                       {"support", std::int64_t{900}},
                                                       {"flag", false},
                                                       {"label", std::string("y")},
                                                       {"mode", std::string("fast")},
                                                       {"inner.a", 4.0}}));
  EXPECT_EQ(p.lo, 1.0);
  EXPECT_EQ(p.hi, 2.0);
  EXPECT_EQ(p.count, 2);
  EXPECT_EQ(p.support, 900u);
  EXPECT_FALSE(p.flag);
  EXPECT_EQ(p.label, "y");
  EXPECT_EQ(p.mode, Mode::kFast);
  EXPECT_EQ(p.inner.a, 4.0);
}

TEST(OptionsBinder, BoundsAreEnforcedWhenParsed) {
  const auto o = binder_options();
  OptionValue v;
  EXPECT_NE(parse_option_value(*o.schema().find("count"), "0", v)->find("at least 1"), std::string::npos);
  EXPECT_NE(parse_option_value(*o.schema().find("count"), "1.5", v)->find("must be an integer"), std::string::npos);
  EXPECT_NE(parse_option_value(*o.schema().find("hi"), "0", v)->find("greater than 0 m"), std::string::npos);
  EXPECT_NE(parse_option_value(*o.schema().find("mode"), "slow", v)->find("one of fast|safe"), std::string::npos);
}

TEST(OptionsBinder, RulesAreEnforcedNamingWhereBlockKeysValuesAndRule) {
  const auto o = binder_options();
  EXPECT_EQ(rule_error(o, {{"lo", 1.0}}), "(no error)");
  // The default message: the rule, each key with its value and unit, and why; at the last given key.
  EXPECT_EQ(rule_error(o, {{"lo", 3.0}}),
            "p.yaml:4: stage 'b' (binder): rule 'lo < hi' is broken: lo = 3 m, hi = 2 m (an interval)");
  EXPECT_EQ(rule_error(o, {{"hi", 0.1}, {"lo", 3.0}}),  // hi at line 4, lo at 5: the formula's last key
            "p.yaml:4: stage 'b' (binder): rule 'lo < hi' is broken: lo = 3 m, hi = 0.1 m (an interval)");
  // A message of the rule's own, with values in place of {key}.
  EXPECT_EQ(rule_error(o, {{"count", std::int64_t{9}}}),
            "p.yaml:4: stage 'b' (binder): option 'count' = 9 must not exceed 'support' = 3");
  // A value given by --set is named so.
  OptionValues v = values_of(o.schema(), {});
  v.set("lo", 5.0);
  v.mark_given("lo", "--set stages.b.lo=5");
  try {
    o.bind(v);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("--set stages.b.lo=5: stage 'b' (binder): rule 'lo < hi'", 0), 0u) << e.what();
  }
  // The shipped sensor rule keeps its message.
  const std::string e = [] {
    try {
      load_pipeline_from_string("input: {scans: x.pcd}\nsensor: {range_min: 40}\nstages: [{type: register}]\n",
                                "p.yaml", "/", LoadOptions{{}, "", false});
    } catch (const ConfigError& err) {
      return std::string(err.what());
    }
    return std::string("(no error)");
  }();
  EXPECT_EQ(e, "p.yaml:2: sensor: range_min (40 m) must be less than range_max (30 m)");
}

TEST(OptionsBinder, DescribeAndDocsListTheRules) {
  const auto o = binder_options();
  const std::string d = describe_schema(o.schema());
  EXPECT_NE(d.find("rules\n  lo < hi: an interval\n  count <= support: why\n"), std::string::npos) << d;
  const std::string md = schema_markdown(o.schema());
  EXPECT_NE(md.find("Rules:\n\n- `lo < hi`: an interval\n- `count <= support`: why\n"), std::string::npos) << md;
  EXPECT_EQ(o.schema().rules[0].keys, (std::vector<std::string>{"lo", "hi"}));
  EXPECT_NE(describe_schema(sensor_schema()).find("range_min < range_max"), std::string::npos);
}

TEST(OptionsBinder, DeclaringAnOptionTwiceIsALogicError) {
  using P = BinderParams;
  Options<P> o;
  o.add("lo", &P::lo, bounds(0, 1), "m", "lower");
  EXPECT_THROW(o.add("lo", &P::hi, bounds(0, 1), "m", "again"), std::logic_error);
  EXPECT_THROW(o.add("flag", &P::flag, "x").add("flag", &P::flag, "y"), std::logic_error);
  // A rule must name a declared option; an integer needs bounds that fit its member.
  EXPECT_THROW(o.rule("nothing < declared", [](const P&) { return true; }, "why"), std::logic_error);
  EXPECT_THROW(o.add("count", &P::count, at_least(0), "", "unbounded"), std::logic_error);
  EXPECT_THROW(o.add("support", &P::support, bounds(-1, 10), "", "negative"), std::logic_error);
  // A retired name is neither declared again nor retired twice.
  EXPECT_THROW(o.retire("lo", "fixed"), std::logic_error);
  o.retire("old", "fixed at 1");
  EXPECT_THROW(o.retire("old", "again"), std::logic_error);
  EXPECT_THROW(o.add("old", &P::hi, bounds(0, 1), "m", "back"), std::logic_error);
  EXPECT_NE(describe_schema(o.schema()).find("refused keys (a configuration that sets one fails, naming what to do instead)\n  old: fixed at 1\n"),
            std::string::npos);
  EXPECT_NE(schema_markdown(o.schema()).find("- `old`: fixed at 1\n"), std::string::npos);
}

TEST(OptionsBinder, DescribeKeepsWideColumnsApart) {
  using P = BinderParams;
  Options<P> o;
  o.add("lo", &P::lo, bounds(-1e9, 1e9), "m", "wide bounds")
      .add("hi", &P::hi, bounds(-3.141592654, 3.141592654), "rad", "an angle");
  const std::string d = describe_schema(o.schema());
  // Every row's bounds end at least two spaces before its unit, and the units start in one column.
  const std::size_t m = d.find("1000000000]  "), r = d.find("3.141592654]  ");
  ASSERT_NE(m, std::string::npos) << d;
  ASSERT_NE(r, std::string::npos) << d;
  const auto column = [&](std::size_t at, const char* unit) { return d.find(unit, at) - d.rfind('\n', at); };
  EXPECT_EQ(column(m, " m "), column(r, " rad ")) << d;
}
