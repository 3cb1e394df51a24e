// Strict configuration (issue 33 items 8, 12, 13, 17, 19): duplicate keys, second documents,
// nesting depth, UTF-8, numbers with trailing bytes, and the simulator's work bound.
#include <gtest/gtest.h>

#include <string>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/pipeline/options.hpp"
#include "pcdp/pipeline/pipeline.hpp"
#include "pcdp/sim/nodding_sim.hpp"

using namespace pcdp;

namespace {
const char* kBase = R"(input:
  scans: scans/*.pcd
output_dir: out
sensor:
  range_max: 30
  range_calibration: {k: 1.0, b: 0.0}
stages:
  - type: register
  - type: fuse_elevation
    resolution: 0.1
)";

LoadOptions no_inputs(std::vector<Override> ov = {}) {
  LoadOptions o;
  o.check_inputs = false;
  o.overrides = std::move(ov);
  return o;
}

/// The ConfigError of loading (and preparing: stage options are checked there), or "(no error)".
std::string error_of(const std::string& yaml, LoadOptions o = no_inputs()) {
  try {
    Pipeline::prepare(load_pipeline_from_string(yaml, "p.yaml", "/base", o));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}

bool has(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }
}  // namespace

TEST(ConfigHardening, TheBaseIsValid) { EXPECT_EQ(error_of(kBase), "(no error)"); }

// ---- item 12: duplicate keys at any depth, second documents ---------------------------------

TEST(ConfigHardening, ADuplicateTopLevelKeyIsRefusedWithBothLines) {
  const std::string e = error_of(std::string(kBase) + "output_dir: elsewhere\n");
  EXPECT_TRUE(has(e, "p.yaml:11:1: duplicate key 'output_dir': given at line 3 and again at line 11")) << e;
}

TEST(ConfigHardening, ADuplicateKeyInsideABlockIsRefusedWithItsPath) {
  std::string y = kBase;
  y.replace(y.find("  range_max: 30\n"), 16, "  range_max: 30\n  range_max: 40\n");
  const std::string e = error_of(y);
  EXPECT_TRUE(has(e, "p.yaml:6:3: duplicate key 'sensor.range_max': given at line 5 and again at line 6")) << e;
}

TEST(ConfigHardening, ADuplicateKeyInAFlowMappingAndInAStageIsRefused) {
  std::string y = kBase;
  y.replace(y.find("{k: 1.0, b: 0.0}"), 16, "{k: 1.0, b: 0.0, k: 2}");
  EXPECT_TRUE(has(error_of(y), "duplicate key 'sensor.range_calibration.k': given at line 6 and again at line 6"))
      << error_of(y);
  const std::string e = error_of(std::string(kBase) + "    resolution: 0.2\n");
  EXPECT_TRUE(has(e, "p.yaml:11:5: duplicate key 'stages[1].resolution': given at line 10 and again at line 11")) << e;
}

TEST(ConfigHardening, TheSameKeyInTwoMappingsIsFine) {
  // 'type' in two stages, 'k' in two blocks: one per mapping is the rule.
  EXPECT_EQ(error_of(std::string(kBase) + "  - {type: fuse_octomap, name: map}\nmount: {x: 1}\n"), "(no error)");
}

TEST(ConfigHardening, DuplicateNullAndAliasedKeysAreRefused) {
  EXPECT_TRUE(has(error_of(std::string(kBase) + "~: 1\nnull: 2\n"), "duplicate key 'null'"));
  EXPECT_TRUE(has(error_of(std::string("&o output_dir: a\n") + kBase + "*o : b\n"), "duplicate key 'output_dir'"));
}

TEST(ConfigHardening, AKeyThatIsAMappingIsRefused) {
  const std::string e = error_of(std::string(kBase) + "? {a: 1}\n: 2\n");
  EXPECT_TRUE(has(e, "a key in '(top level)' is a mapping or a list")) << e;
}

TEST(ConfigHardening, ASecondDocumentIsRefused) {
  const std::string e = error_of(std::string(kBase) + "---\noutput_dir: other\n");
  EXPECT_TRUE(has(e, "p.yaml:11:1: a second YAML document begins here")) << e;
  EXPECT_TRUE(has(error_of(std::string("---\n") + kBase + "...\n---\n"), "a second YAML document"));
  // One document with its markers is fine.
  EXPECT_EQ(error_of(std::string("---\n") + kBase + "...\n"), "(no error)");
}

TEST(ConfigHardening, RepeatedSetOverridesApplyInOrderTheLastWins) {
  const PipelineConfig c = load_pipeline_from_string(
      kBase, "p.yaml", "/base", no_inputs({{"sensor.range_max", "20"}, {"sensor.range_max", "25"}}));
  EXPECT_DOUBLE_EQ(c.sensor.range_max, 25.0);
  // A whole block given later replaces what came before it, as in the file.
  const PipelineConfig d = load_pipeline_from_string(
      kBase, "p.yaml", "/base", no_inputs({{"sensor.range_max", "25"}, {"sensor", "{range_min: 0.5}"}}));
  EXPECT_DOUBLE_EQ(d.sensor.range_max, 30.0);  // the default
  EXPECT_DOUBLE_EQ(d.sensor.range_min, 0.5);
}

TEST(ConfigHardening, ASetValueIsHeldToTheSameRules) {
  EXPECT_TRUE(has(error_of(kBase, no_inputs({{"sensor", "{range_max: 5, range_max: 6}"}})),
                  "--set sensor:1:16: duplicate key 'range_max'"));
  EXPECT_TRUE(has(error_of(kBase, no_inputs({{"output_dir", "a\n---\nb"}})), "a second YAML document"));
  // Text that is not YAML is taken as it is.
  const PipelineConfig c =
      load_pipeline_from_string(kBase, "p.yaml", "/base", no_inputs({{"output_dir", "out: [unclosed"}}));
  EXPECT_EQ(c.output_dir, "out: [unclosed");
}

// ---- item 17: the nesting bound, counted from the parse, not from the characters ------------

TEST(ConfigHardening, BracketsInCommentsAndQuotesDoNotCountAsNesting) {
  const std::string brackets(200, '[');
  std::string y = kBase;
  y = "# " + brackets + "\n" + y + "description: \"" + brackets + "\"\n";
  EXPECT_EQ(error_of(y), "(no error)");
  // An apostrophe in a comment no longer switches the check off.
  std::string deep = "# it's a comment\ndescription: " + std::string(100, '[') + std::string(100, ']') + "\n";
  EXPECT_TRUE(has(error_of(std::string(kBase) + deep), "not valid YAML: nested more than 64 levels deep")) << error_of(std::string(kBase) + deep);
}

TEST(ConfigHardening, DeepBlockNestingIsBoundedToo) {
  std::string y = std::string(kBase) + "description:\n";
  for (int d = 1; d <= 80; ++d) y += std::string(static_cast<std::size_t>(2 * d), ' ') + "k" + std::to_string(d) + ":\n";
  const std::string e = error_of(y);
  EXPECT_TRUE(has(e, "nested more than 64 levels deep (at 'description.k1.k2")) << e;
}

TEST(ConfigHardening, VeryDeepFlowNestingFailsCleanly) {
  const std::string y = std::string(kBase) + "description: " + std::string(200000, '[') + std::string(200000, ']') + "\n";
  EXPECT_TRUE(has(error_of(y), "p.yaml:11:77: not valid YAML: nested more than 64 levels deep")) << error_of(y);
  // Unclosed: yaml-cpp reads the second '[' as a key; refused as such, before any recursion.
  const std::string open = std::string(kBase) + "description: " + std::string(200000, '[') + "\n";
  EXPECT_TRUE(has(error_of(open), "p.yaml:11:15: a key in 'description[0]' is a mapping or a list")) << error_of(open);
}

// ---- item 8: text is UTF-8, paths are bytes --------------------------------------------------

TEST(ConfigHardening, InvalidUtf8InTheFileIsRefusedWithKeyAndByte) {
  std::string y = kBase;
  y.replace(y.find("type: register"), 14, "type: register\n    name: reg\xE9");
  const std::string e = error_of(y);
  EXPECT_TRUE(has(e, "p.yaml:9:11: the value of 'stages[0].name': byte 3 (0xE9) is not valid UTF-8")) << e;
  const std::string k = error_of(std::string(kBase) + "caf\xC3\xA9\xFF: 1\n");
  EXPECT_TRUE(has(k, "p.yaml:11:1: key: byte 5 (0xFF) is not valid UTF-8")) << k;
}

TEST(ConfigHardening, SetValuesMustBeUtf8ExceptPaths) {
  const std::string e = error_of(kBase, no_inputs({{"stages.register.name", "x\xC3"}}));
  EXPECT_TRUE(has(e, "byte 1 of the value of 'stages.register.name' is not valid UTF-8")) << e;
  EXPECT_TRUE(has(error_of(kBase, no_inputs({{"sensor.range_max\xFF", "1"}})), "byte 16 of the key is not valid UTF-8"));
  // A Latin-1 file name is a legal path on Linux.
  const PipelineConfig c = load_pipeline_from_string(kBase, "p.yaml", "/base", no_inputs({{"output_dir", "caf\xE9"}}));
  EXPECT_EQ(c.output_dir, "caf\xE9");
}

TEST(ConfigHardening, Utf8Validator) {
  EXPECT_FALSE(invalid_utf8_offset("plain ascii, caf\xC3\xA9, \xE2\x82\xAC, \xF0\x9F\x98\x80"));
  EXPECT_EQ(invalid_utf8_offset("ab\xC0\xAF"), 2u);        // overlong
  EXPECT_EQ(invalid_utf8_offset("\xED\xA0\x80"), 0u);      // surrogate
  EXPECT_EQ(invalid_utf8_offset("x\xF4\x90\x80\x80"), 1u);  // above U+10FFFF
  EXPECT_EQ(invalid_utf8_offset("ab\xE2\x82"), 2u);        // cut short
  EXPECT_EQ(invalid_utf8_offset("\x80"), 0u);
}

TEST(ConfigHardening, TheReportWritesAPathThatIsNotUtf8) {
  PipelineConfig cfg = load_pipeline_from_string(kBase, "p.yaml", "/base", no_inputs());
  cfg.scans = {"/data/caf\xE9.pcd"};
  RunSummary sum;
  const std::string js = report_json(cfg, sum);
  EXPECT_TRUE(has(js, "caf\xEF\xBF\xBD.pcd")) << js;  // U+FFFD in place of the byte
}

// ---- item 13: numbers and lists with trailing bytes -----------------------------------------

TEST(ConfigHardening, ExtentWithTrailingJunkIsRefusedNamingStageKeyValueRule) {
  const auto with_extent = [](const std::string& v) { return std::string(kBase) + "    extent: \"" + v + "\"\n"; };
  EXPECT_EQ(error_of(with_extent("-10,-10,20,10")), "(no error)");
  EXPECT_EQ(error_of(with_extent(" -10, -10 ,20,10 ")), "(no error)");
  for (const std::string bad : {"-10,-10,20,10,junk", "-10,-10,20,10junk", "-10,-10,20", "-10,,20,10", "0x1,0,2,2",
                                "nan,0,1,1", "-10,-10,20,10,"}) {
    const std::string e = error_of(with_extent(bad));
    EXPECT_TRUE(has(e, "stage 'fuse_elevation' (fuse_elevation): option 'extent' = '" + bad +
                           "' must be xmin,ymin,xmax,ymax"))
        << bad << ": " << e;
  }
  EXPECT_TRUE(has(error_of(with_extent("-10,-10,20,10,junk")), "(it has 5 comma-separated values, needs 4)"));
  EXPECT_TRUE(has(error_of(with_extent("-10,-10,20,10junk")), "(it '10junk' is not a finite number)"));
}

TEST(ConfigHardening, NumbersAreDecimalWithNothingAround) {
  OptionValue v;
  const OptionSpec d = opt_double("d", 0.0, std::nullopt, std::nullopt, "", "");
  const OptionSpec i = opt_int("i", 0, std::nullopt, std::nullopt, "", "");
  for (const std::string bad : {"1.5junk", " 1.5", "0x10", "1.5 ", "", "1,5", "1e999"})
    EXPECT_TRUE(parse_option_value(d, bad, v).has_value()) << "'" << bad << "'";
  for (const std::string bad : {"3x", " 3", "3.0", "1e3", "0x10", "99999999999999999999"})
    EXPECT_TRUE(parse_option_value(i, bad, v).has_value()) << "'" << bad << "'";
  EXPECT_EQ(*parse_option_value(d, "inf", v), "must be a finite number");
  for (const std::string good : {"1.5", "-2", "+3e-2", ".5", "1E3", "1e-320"}) EXPECT_FALSE(parse_option_value(d, good, v)) << good;
  EXPECT_EQ(*parse_option_value(d, "1e-400", v), "is too small for a double (it would read as 0)");  // an underflow to 0 would turn an option off
  const std::string e = error_of(std::string(kBase) + "    band: 0.5m\n");
  EXPECT_TRUE(has(e, "p.yaml:11: stage 'fuse_elevation' (fuse_elevation): option 'band' = '0.5m' must be a number")) << e;
}

TEST(ConfigHardening, SceneNumbersAreStrictToo) {
  const std::string scene = "boxes:\n  - {min: [0, 0, 0], max: [1, 1, 1], reflectivity: R}\n";
  const auto err = [&](const std::string& r) {
    std::string s = scene;
    s.replace(s.find('R'), 1, r);
    try {
      load_scene_from_string(s, "scene.yaml");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_EQ(err("0.5"), "(no error)");
  EXPECT_TRUE(has(err("0.5junk"), "box: reflectivity '0.5junk' must be in [0, 1]"));
  EXPECT_TRUE(has(err("''"), "box: reflectivity '' must be in [0, 1]"));  // was taken as 0
  EXPECT_TRUE(has(err("[1]"), "box: reflectivity"));
  std::string s = scene;
  s.replace(s.find("[1, 1, 1]"), 9, "[1, 1, 0x1]");
  s.replace(s.find('R'), 1, "0.5");
  EXPECT_THROW(load_scene_from_string(s, "scene.yaml"), ConfigError);
}

// ---- item 19: simulate refuses scenes it cannot finish ---------------------------------------

TEST(ConfigHardening, SimulateRefusesWorkBeyondItsBound) {
  const auto err = [](const std::string& s) {
    try {
      load_scene_from_string(s, "scene.yaml");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_EQ(err("passes: 4\nlines_per_pass: 75\nscanner: {beams: 241}\n"), "(no error)");
  const std::string returns = err("passes: 10\nlines_per_pass: 100000\nscanner: {beams: 181}\n");
  EXPECT_TRUE(has(returns, "scene.yaml: the scene needs passes x lines_per_pass x scanner.beams = 10 x 100000 x 181"))
      << returns;
  const std::string rays = err("passes: 10\nlines_per_pass: 1000\nscanner: {beams: 181, subrays: 1000}\n");
  EXPECT_TRUE(has(rays, "x scanner.subrays")) << rays;
  const std::string poses = err("lines_per_pass: 1000\nscanner: {beams: 1, line_period: 10}\nmotion: {pose_rate: 10000}\n");
  EXPECT_TRUE(has(poses, "motion.pose_rate")) << poses;
}

TEST(ConfigHardening, AQuoteLeftOpenIsPointedAtWhereItsLineIs) {
  // YAML lets a quoted value run over lines: the open quote swallows `stages`, and the error
  // (about the missing key) says which line opened it.
  const std::string e = error_of("input:\n  scans: \"scans/*.pcd\noutput_dir: out\nstages:\n  - type: register\n");
  EXPECT_TRUE(has(e, "required key 'stages' is missing")) << e;
  EXPECT_TRUE(has(e, "p.yaml:2 opens a quoted value that the line does not close")) << e;
  // Quotes closed on their lines (escapes, '' in single quotes, a quote in a comment, flow
  // mappings): an error elsewhere gets no note.
  const std::string ok = error_of(
      "input:\n  scans: 'it''s/*.pcd'  # a \"comment\n  poses: \"a\\\"b.csv\"\noutput_dir: \"out\"\n"
      "stages: [{type: \"register\", bogus: 1}]\n");
  EXPECT_TRUE(has(ok, "bogus")) << ok;
  EXPECT_FALSE(has(ok, "opens a quoted value")) << ok;
  // Quotes inside plain scalars and block scalars open nothing.
  for (const std::string text : {"description: rock-'n'-roll\n", "description: fast,'ish\n", "description: 5\" rack\n",
                                 "description: |\n  'Twas a scan\n  \"of the yard\n", "description: >-\n  it's \"x\n"}) {
    const std::string e2 = error_of(text + "input:\n  scans: scans/*.pcd\nstages: [{type: register, bogus: 1}]\n");
    EXPECT_TRUE(has(e2, "bogus")) << text << e2;
    EXPECT_FALSE(has(e2, "opens a quoted value")) << text << e2;
  }
  // A quote left open in a sequence item or a flow mapping is found too.
  EXPECT_TRUE(has(error_of("input:\n  scans:\n    - \"scans/a.pcd\nstages:\n  - type: register\n"), "p.yaml:3 opens"));
  EXPECT_TRUE(has(error_of("input: {scans: \"scans/a.pcd}\nstages:\n  - type: register\n"), "p.yaml:1 opens"));
  // After a block scalar's text, the next key's line is read again.
  EXPECT_TRUE(has(error_of("description: |\n  it's text\ninput:\n  scans: \"scans/*.pcd\nstages:\n  - type: register\n"),
                  "p.yaml:4 opens"));
}

TEST(ConfigHardening, AnOctoMapRangeIsMinusOneOrPositive) {
  // -1 is unlimited; 0 and values between -1 and 0 mean no range, and are refused.
  for (const char* v : {"0", "-0.5"}) {
    const std::string e = error_of(std::string(kBase) + "  - type: fuse_octomap\n    max_range: " + v + "\n");
    EXPECT_TRUE(has(e, "option 'max_range' = " + std::string(v) + " must be -1 (unlimited) or a positive range")) << e;
  }
  for (const char* v : {"-1", "0.001", "30"})
    EXPECT_EQ(error_of(std::string(kBase) + "  - type: fuse_octomap\n    max_range: " + v + "\n"), "(no error)") << v;
}
