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
