// The line streaming API against the batch run: identical labels and points,
// each line finished exactly lines_ahead() lines after it arrives, live poses
// equal to a pose file, and clear errors.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/io/pcd.hpp"
#include "pcdp/io/poses.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pcdp/pipeline/pipeline.hpp"
#include "pcdp/pipeline/stream.hpp"
#include "pcdp_test_paths.hpp"
#include "test_support.hpp"

using namespace pcdp;

namespace {
// The sample pipeline (pipelines/nodding_terrain.yaml) cut to the stages that
// stream.
std::string streaming_yaml(const std::string &out_dir, bool with_poses,
                           const std::string &mixed_options = "") {
  std::ifstream in(std::string(PCDP_SOURCE_DIR) +
                   "/pipelines/nodding_terrain.yaml");
  std::ostringstream y;
  for (std::string l; std::getline(in, l);) {
    if (l.find("check_consistency") != std::string::npos ||
        l.find("fuse_") != std::string::npos)
      continue;
    if (l.rfind("  poses:", 0) == 0 && !with_poses)
      continue;
    if (l.rfind("output_dir:", 0) == 0)
      continue;
    if (l.rfind("stages:", 0) == 0)  // before the stage list, which callers may extend
      y << "output_dir: " << out_dir << "\n";
    y << l << "\n";
    if (l.find("type: reject_mixed_pixels") != std::string::npos &&
        !mixed_options.empty())
      y << "    " << mixed_options << "\n";
  }
  return y.str();
}

PipelineConfig streaming_config(const std::string &out_dir, bool with_poses,
                                const std::string &mixed_options = "") {
  return load_pipeline_from_string(streaming_yaml(out_dir, with_poses,
                                                  mixed_options),
                                   "streaming.yaml",
                                   std::string(PCDP_SOURCE_DIR) + "/pipelines");
}

ScanLine line_of(const Pass &p, std::size_t k) {
  ScanLine l;
  const std::size_t b = p.line_begin[k], e = p.line_begin[k + 1];
  l.line = p.line[b];
  l.nod = p.nod[b];
  l.range.assign(p.range.begin() + static_cast<long>(b),
                 p.range.begin() + static_cast<long>(e));
  l.bearing.assign(p.bearing.begin() + static_cast<long>(b),
                   p.bearing.begin() + static_cast<long>(e));
  l.amplitude.assign(p.amplitude.begin() + static_cast<long>(b),
                     p.amplitude.begin() + static_cast<long>(e));
  l.stamp.assign(p.stamp.begin() + static_cast<long>(b),
                 p.stamp.begin() + static_cast<long>(e));
  return l;
}

struct Streamed {
  std::vector<Label> label;
  std::vector<std::uint8_t> flags;  ///< the evidence bits (kFlag*), as returns.pcd's `flags`
  std::vector<double> x, y, z;
};

// Feeds every sample pass line by line; checks that line k comes out when line
// k + ahead arrives.
Streamed stream_all(LineStream &s, const std::vector<std::string> &scans) {
  const bool check_timing = s.block_lines() == 1;
  Streamed out;
  const auto take = [&](const std::vector<Pass> &lines) {
    for (const Pass &o : lines)
      for (std::size_t i = 0; i < o.size(); ++i) {
        out.label.push_back(o.label[i]);
        out.flags.push_back(o.flags[i]);
        out.x.push_back(o.x[i]);
        out.y.push_back(o.y[i]);
        out.z.push_back(o.z[i]);
      }
  };
  for (std::size_t f = 0; f < scans.size(); ++f) {
    const Pass p = read_pass(scans[f], f);
    std::size_t finished = 0;
    for (std::size_t k = 0; k < p.line_count(); ++k) {
      const auto lines = s.push(line_of(p, k));
      finished += lines.size();
      // Exactly the lines whose forward context is complete.
      if (check_timing) {
        EXPECT_EQ(finished, k + 1 > static_cast<std::size_t>(s.lines_ahead())
                                ? k + 1 - s.lines_ahead()
                                : 0u);
      }
      if (check_timing && !lines.empty()) {
        EXPECT_EQ(lines.back().line[0],
                  p.line[p.line_begin[k - static_cast<std::size_t>(
                                              s.lines_ahead())]]);
      }
      take(lines);
    }
    const auto rest = s.end_pass();
    EXPECT_EQ(finished + rest.size(), p.line_count());
    take(rest);
  }
  return out;
}
} // namespace

TEST(Stream, LineByLineEqualsTheBatchRun) {
  const std::string dir = test::fresh_dir();
  const PipelineConfig cfg = streaming_config(dir + "/batch", true);
  Pipeline::prepare(cfg).run();
  const io::PcdTable t = io::read_pcd(dir + "/batch/returns.pcd");
  const auto label = test::column(t, "label"), flags = test::column(t, "flags"), x = test::column(t, "x"),
             y = test::column(t, "y"), z = test::column(t, "z");

  for (const std::size_t block : {1, 7}) {
    LineStream s(streaming_config(dir + "/unused", true), block);
    EXPECT_GE(s.lines_ahead(),
              10); // register 1 + the two reject windows across lines
    const Streamed st = stream_all(s, cfg.scans);
    ASSERT_EQ(st.label.size(), label.size());
    std::size_t label_diff = 0, point_diff = 0, rejected = 0;
    for (std::size_t i = 0; i < label.size(); ++i) {
      label_diff += static_cast<double>(st.label[i]) != label[i] || static_cast<double>(st.flags[i]) != flags[i];
      rejected += st.label[i] != Label::kKept;
      const bool both_nan = std::isnan(x[i]) && std::isnan(st.x[i]);
      if (!both_nan &&
          (static_cast<float>(st.x[i]) != static_cast<float>(x[i]) ||
           static_cast<float>(st.y[i]) != static_cast<float>(y[i]) ||
           static_cast<float>(st.z[i]) != static_cast<float>(z[i])))
        ++point_diff;
    }
    EXPECT_EQ(label_diff, 0u);
    EXPECT_EQ(point_diff, 0u);
    EXPECT_GT(rejected, 1000u); // the stages did reject (no-return, occlusion,
                                // mixed pixels ...)
  }
}

TEST(Stream, AWideFootprintsExtraRoundsStreamAsTheBatchRun) {
  // With a footprint 2.5 beam steps wide (25 mrad on the sample's 10 mrad steps),
  // reject_mixed_pixels runs two more rounds, each looking 3 lines across at the
  // labels of the round before (with across_lines off, 1 line: a side's 2-D
  // patch reads whether the same beam on the lines before and after is usable,
  // which the round before may have changed): its reach covers all three rounds.
  for (const std::string mixed : {"", "across_lines: false"}) {
    SCOPED_TRACE(mixed);
    const std::string dir = test::fresh_dir();
    const auto with_divergence = [&](const std::string &out, const char *div) {
      std::string y = streaming_yaml(out, true, mixed);
      const std::string from = "beam_divergence: 0.008";
      const auto at = y.find(from);
      EXPECT_NE(at, std::string::npos);
      y.replace(at, from.size(), std::string("beam_divergence: ") + div);
      // Without reject_occlusion (whose model also reads the divergence), the divergence changes
      // only the number of rounds.
      const std::string occ = "  - type: reject_occlusion\n";
      const auto o = y.find(occ);
      EXPECT_NE(o, std::string::npos);
      y.erase(o, occ.size());
      return load_pipeline_from_string(y, "streaming.yaml",
                                       std::string(PCDP_SOURCE_DIR) + "/pipelines");
    };
    const auto mixed_in = [](const std::vector<double> &label) {
      std::size_t n = 0;
      for (const double l : label) n += static_cast<Label>(l) == Label::kMixedPixel;
      return n;
    };
    const PipelineConfig cfg = with_divergence(dir + "/batch", "0.025");
    Pipeline::prepare(cfg).run();
    const io::PcdTable batch = io::read_pcd(dir + "/batch/returns.pcd");
    const auto label = test::column(batch, "label"), flags = test::column(batch, "flags");
    // Just under one beam step: no extra round along the lines (across them, only where the nod
    // moves the beam by less than the footprint between lines: on the sample, 13 mrad a line, only
    // where the nod turns).
    Pipeline::prepare(with_divergence(dir + "/one_round", "0.0099")).run();
    const auto one_round =
        test::column(io::read_pcd(dir + "/one_round/returns.pcd"), "label");
    EXPECT_GT(mixed_in(label), mixed_in(one_round));  // the extra rounds found more

    LineStream s(with_divergence(dir + "/unused", "0.025"), 1);
    // Without across_lines: register's 1 line, and the stage's 1 plus one per extra round (no
    // scene tried needed all of it, but each round can pass a label one line on).
    if (!mixed.empty()) {
      EXPECT_EQ(s.lines_ahead(), 1 + 3);
    }
    const Streamed st = stream_all(s, cfg.scans);
    ASSERT_EQ(st.label.size(), label.size());
    std::size_t label_diff = 0, runs = 0;
    for (std::size_t i = 0; i < label.size(); ++i) {
      label_diff += static_cast<double>(st.label[i]) != label[i] || static_cast<double>(st.flags[i]) != flags[i];
      runs += (static_cast<unsigned>(flags[i]) & kFlagMixedRun) != 0;
    }
    EXPECT_EQ(label_diff, 0u);  // labels and their evidence bits
    EXPECT_GT(runs, 0u);        // the later rounds' returns say so
  }
}

TEST(Stream, LivePosesGiveTheSameAsThePoseFile) {
  const std::string dir = test::fresh_dir();
  const PipelineConfig with_file = streaming_config(dir, true);
  LineStream a(with_file);
  LineStream b(streaming_config(dir, false));
  const std::vector<PoseSample> poses =
      io::read_pose_csv(with_file.poses, with_file.rpy_order).samples();
  // Poses arrive as the lines do: every pose up to a line's last stamp (plus
  // the next one, the interpolation bracket) before the line.
  std::size_t next_pose = 0;
  const Pass p = read_pass(with_file.scans[0], 0);
  std::vector<Pass> out_a, out_b;
  for (std::size_t k = 0; k < p.line_count(); ++k) {
    const double t_end = p.stamp[p.line_begin[k + 1] - 1];
    while (next_pose < poses.size() &&
           (next_pose == 0 || poses[next_pose - 1].stamp <= t_end))
      b.add_pose(poses[next_pose++]);
    for (auto &o : a.push(line_of(p, k)))
      out_a.push_back(std::move(o));
    for (auto &o : b.push(line_of(p, k)))
      out_b.push_back(std::move(o));
  }
  for (auto &o : a.end_pass())
    out_a.push_back(std::move(o));
  for (auto &o : b.end_pass())
    out_b.push_back(std::move(o));
  ASSERT_EQ(out_a.size(), p.line_count());
  ASSERT_EQ(out_b.size(), out_a.size());
  for (std::size_t k = 0; k < out_a.size(); ++k) {
    EXPECT_EQ(out_a[k].label, out_b[k].label) << k;
    for (std::size_t i = 0; i < out_a[k].size(); ++i)
      if (std::isfinite(out_a[k].x[i])) {
        EXPECT_EQ(out_a[k].x[i], out_b[k].x[i]);
      }
  }
}

TEST(Stream, StagesThatNeedWholePassesAndBadLinesAreRefused) {
  const std::string dir = test::fresh_dir();
  std::string yaml = streaming_yaml(dir, true) + "  - type: fuse_elevation\n";
  try {
    LineStream s(load_pipeline_from_string(
        yaml, "s.yaml", std::string(PCDP_SOURCE_DIR) + "/pipelines"));
    FAIL() << "fuse_elevation streamed";
  } catch (const ConfigError &e) {
    EXPECT_NE(std::string(e.what()).find(
                  "'fuse_elevation' (fuse_elevation) cannot stream"),
              std::string::npos)
        << e.what();
  }
  LineStream s(streaming_config(dir, true));
  const Pass p = read_pass(streaming_config(dir, true).scans[0], 0);
  ScanLine l = line_of(p, 0);
  l.bearing.pop_back();
  try {
    s.push(l);
    FAIL() << "a short bearing array was taken";
  } catch (const InputError &e) {
    EXPECT_NE(std::string(e.what()).find("one value per return"),
              std::string::npos)
        << e.what();
  }
  ScanLine late = line_of(p, 0);
  late.stamp.back() = late.stamp.front() - 1.0;  // the last return before the first
  try {
    s.push(late);
    FAIL() << "stamps going back were taken";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("return 240: field 'stamp' must increase"), std::string::npos) << e.what();
  }
  s.push(line_of(p, 0));  // the refused lines changed nothing: the good line is taken
  s.push(line_of(p, 1));
  try {
    s.push(line_of(p, 0));  // goes back in time
    FAIL() << "a line out of order was taken";
  } catch (const InputError &e) {
    EXPECT_NE(std::string(e.what()).find("field 'line' must increase"),
              std::string::npos)
        << e.what();
  }
}
