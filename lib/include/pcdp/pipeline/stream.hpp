// Line streaming API for live mapping stacks: feed scan lines as they arrive (a LaserScan-like
// array of ranges, bearings and amplitudes, the encoder reading taken at the end of the line, and
// the vehicle poses as they come) and receive registered, labelled lines.
//
//   pcdp::LineStream s(pcdp::load_pipeline("live.yaml"));   // register + reject stages
//   s.add_pose(pose);                                         // whenever a pose arrives
//   for (const pcdp::Pass& out : s.push(line)) use(out);      // 0 or more finished lines
//   for (const pcdp::Pass& out : s.end_pass()) use(out);      // at the end of a nod sweep
//
// A stage's result for a line depends on the lines around it (register: the previous encoder
// reading; reject_occlusion and reject_mixed_pixels: their `window` across lines). A line is
// finished as soon as the lines it depends on have arrived, no later: lines_ahead() lines after
// it. It is computed on a window of lines that holds everything its result depends on, so the
// output is identical to the batch run of the same pass (tests/unit/pipeline/test_stream.cpp checks it).
// Only labellers with a reach stream (Stage::kind, Stage::reach): accumulators (the fusion
// stages) and two-phase stages (check_consistency) need whole passes; a streaming pipeline must
// not list them (feed the finished lines to your own map instead).
//
// Coordinates: the finished lines hold doubles in absolute map coordinates (no map origin, unlike
// a batch run's products: pcdp/core/georef.hpp). With georeferenced poses, subtract an origin of your
// choice before converting them to float.
#pragma once

#include <deque>
#include <memory>
#include <vector>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/pipeline/stage.hpp"
#include "pcdp/core/transforms.hpp"

namespace pcdp {

/// One scan line as the scanner delivers it.
struct ScanLine {
  std::uint32_t line = 0;        ///< increasing over the run
  float nod = 0.0f;              ///< encoder reading (rad), taken at the stamp of the last return
  std::vector<float> range;      ///< m; 0 = no return
  std::vector<float> bearing;    ///< rad
  std::vector<float> amplitude;  ///< empty or one per return (NaN: not measured)
  std::vector<double> stamp;     ///< s, one per return, increasing
};

class LineStream {
 public:
  /// Builds the pipeline's stages (a pose file in the config is loaded; more poses may be added
  /// live). Throws ConfigError naming the first stage that cannot stream.
  /// `block_lines`: finish lines in blocks of this many (each window is computed once per block:
  /// less work per line, block_lines - 1 more lines of delay). 1 = every line as soon as possible.
  /// `stages`: where the stage types are looked up (builtin_stages() plus an embedder's own).
  explicit LineStream(PipelineConfig config, std::size_t block_lines = 1,
                      const std::vector<StageInfo>& stages = builtin_stages());
  ~LineStream();
  LineStream(LineStream&&) noexcept;
  LineStream& operator=(LineStream&&) noexcept;

  /// Adds a vehicle pose (T_M_V) after the last one.
  void add_pose(const PoseSample& pose);
  /// Adds the next line of the current pass; returns the lines that are now finished, in order.
  /// Throws InputError if the line breaks the data contract (sizes, order, stamps).
  std::vector<Pass> push(const ScanLine& line);
  /// Ends the current pass (a nod sweep): finishes its remaining lines. The next push starts a
  /// new pass.
  std::vector<Pass> end_pass();

  /// Lines a line waits for before it is finished (block_lines = 1).
  int lines_ahead() const { return ahead_; }
  std::size_t block_lines() const { return block_; }
  /// The stages' time and metrics so far. Lines are processed in overlapping windows, so the
  /// metrics count window work (a line is seen up to 2 lines_ahead() + 1 times).
  const std::vector<StageReport>& reports() const { return reports_; }

 private:
  std::vector<Pass> finish(std::size_t upto, bool to_end);

  std::shared_ptr<PipelineConfig> config_;
  std::shared_ptr<PoseTrack> poses_;
  RunContext context_;
  std::vector<std::unique_ptr<Stage>> stages_;
  std::vector<StageReport> reports_;
  int ahead_ = 0;
  std::size_t block_ = 1;
  std::deque<ScanLine> lines_;   ///< buffered lines of the current pass
  std::size_t first_ = 0;        ///< pass-relative index of lines_.front()
  std::size_t next_out_ = 0;     ///< pass-relative index of the next line to finish
  std::size_t pass_index_ = 0;
  std::int64_t last_line_ = -1;
  double last_stamp_ = -1e300;
};

}  // namespace pcdp
