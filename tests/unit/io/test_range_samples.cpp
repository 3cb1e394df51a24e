#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/range_samples.hpp"
#include "test_support.hpp"

using namespace pcdp;

TEST(RangeSamples, ReadsTheTrueAndMeasuredColumnsByName) {
  const std::string dir = test::fresh_dir();
  test::write_text(dir + "/c.csv", "note,measured,true\nx,1.01,1\n\ny,2.02,2\r\n");
  std::vector<double> y, z;
  io::read_range_samples_csv(dir + "/c.csv", y, z);
  EXPECT_EQ(y, (std::vector<double>{1.0, 2.0}));
  EXPECT_EQ(z, (std::vector<double>{1.01, 2.02}));
}

TEST(RangeSamples, BadFilesNameTheLineAndTheRule) {
  const std::string dir = test::fresh_dir();
  test::write_text(dir + "/c.csv", "distance,range\n1,1\n");
  std::vector<double> y, z;
  try {
    io::read_range_samples_csv(dir + "/c.csv", y, z);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("must name the columns 'true' and 'measured'"), std::string::npos);
  }
  test::write_text(dir + "/c.csv", "true,measured\n1,1\n2,abc\n");
  try {
    io::read_range_samples_csv(dir + "/c.csv", y, z);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("c.csv:3: column 'measured': 'abc' is not a finite number"), std::string::npos);
  }
}
