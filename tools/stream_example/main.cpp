// How a live mapping stack uses the line streaming API (pcdp/pipeline/stream.hpp), replaying recorded
// passes as if they arrived from the scanner: poses are handed over as they come, each scan line
// is pushed when its encoder reading is taken, and finished lines come back registered and
// labelled, ready for the stack's own map. Prints the added latency per line.
//
//   pcdp_stream_example PIPELINE.yaml   (register and reject stages only; e.g. pipelines/streaming.yaml)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <vector>

#include "pcdp/pipeline/config.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pcdp/pipeline/stream.hpp"

int main(int argc, char** argv) {
  if (argc != 2 && argc != 3) {
    std::fprintf(stderr, "usage: %s PIPELINE.yaml [BLOCK_LINES]\n", argv[0]);
    return 2;
  }
  const std::size_t block = argc == 3 ? std::strtoul(argv[2], nullptr, 10) : 1;
  try {
    pcdp::PipelineConfig cfg = pcdp::load_pipeline(argv[1]);
    const std::vector<std::string> scans = cfg.scans;
    pcdp::LineStream stream(std::move(cfg), block);  // the pose file, if any, is loaded; live poses could be added

    std::vector<double> compute_ms;  // time spent in push() per line
    std::size_t lines = 0, points = 0, kept = 0;
    const auto consume = [&](const std::vector<pcdp::Pass>& done) {
      for (const pcdp::Pass& line : done) {  // here a stack would insert the kept points into its map
        points += line.size();
        for (std::size_t i = 0; i < line.size(); ++i) kept += line.is_kept(i);
      }
    };
    double line_period = 0;
    for (std::size_t f = 0; f < scans.size(); ++f) {
      const pcdp::Pass pass = pcdp::read_pass(scans[f], f);
      for (std::size_t k = 0; k < pass.line_count(); ++k) {
        const std::size_t b = pass.line_begin[k], e = pass.line_begin[k + 1];
        pcdp::ScanLine l;  // what the driver delivers: one LaserScan-like array and the encoder
        l.line = pass.line[b];
        l.nod = pass.nod[b];
        l.range.assign(pass.range.begin() + static_cast<long>(b), pass.range.begin() + static_cast<long>(e));
        l.bearing.assign(pass.bearing.begin() + static_cast<long>(b), pass.bearing.begin() + static_cast<long>(e));
        l.amplitude.assign(pass.amplitude.begin() + static_cast<long>(b), pass.amplitude.begin() + static_cast<long>(e));
        l.stamp.assign(pass.stamp.begin() + static_cast<long>(b), pass.stamp.begin() + static_cast<long>(e));
        if (k > 0) line_period = pass.stamp[e - 1] - pass.stamp[b - 1];
        const auto t0 = std::chrono::steady_clock::now();
        const auto done = stream.push(l);
        compute_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        consume(done);
        ++lines;
      }
      consume(stream.end_pass());  // the sweep ended: its last lines are finished now
    }
    std::sort(compute_ms.begin(), compute_ms.end());
    const auto pct = [&](double q) { return compute_ms[static_cast<std::size_t>(q * static_cast<double>(compute_ms.size() - 1))]; };
    std::printf("stream: %zu lines, %zu returns, %zu kept\n", lines, points, kept);
    const double wait = static_cast<double>(stream.lines_ahead()) + static_cast<double>(block - 1);
    double total = 0;
    for (const double t : compute_ms) total += t;
    std::printf("block %zu: added latency per line: compute in push() p50 %.3f ms, p99 %.3f ms, max %.3f ms, mean %.3f ms "
                "(%.0f returns/s); waiting for context: up to %.0f lines (%.1f ms at %.1f ms/line)\n",
                block, pct(0.5), pct(0.99), compute_ms.back(), total / static_cast<double>(lines),
                static_cast<double>(points) / (total * 1e-3), wait, wait * line_period * 1e3, line_period * 1e3);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pcdp_stream_example: %s\n", e.what());
    return 1;
  }
}
