// Helpers shared by the tests: temporary folders, running the CLI, reading outputs.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "pcdp/io/pcd.hpp"
#include "pcdp/pipeline/stage.hpp"
#include "pcdp/sim/nodding_sim.hpp"

namespace pcdp::test {

/// A fresh, empty folder under the build tree's test tmp dir, named after the current test.
std::string fresh_dir(const std::string& tag = "");

struct CliResult {
  int exit_code = -1;
  std::string out;  ///< stdout
  std::string err;  ///< stderr
};
/// Runs the real pcd_pipeline binary with `args` (shell-quoted here), in `cwd` when given.
CliResult run_cli(const std::vector<std::string>& args, const std::string& cwd = "");

void write_text(const std::string& path, const std::string& text);
std::string read_text(const std::string& path);

/// The "# prepare: ARGS" line of a shipped pipeline (e.g. its import) as arguments, ${SHARED}
/// replaced and its --output-dir pointed at `out_dir`; empty if the file has none.
std::vector<std::string> prepare_args(const std::string& yaml, const std::string& out_dir);

/// A small simulated run (vehicle moving with sway, constant-rate nod) with exact truth.
sim::SimConfig small_sim_config();

/// A pipeline YAML for a run written by sim::write_run into `dir`.
std::string pipeline_yaml(const sim::SimConfig& cfg, const std::string& dir, const std::string& out_dir,
                          const std::string& extra_register_options = "");

/// The InputError message of reading `content` as a pass (a fresh file), or "(no error)".
std::string pass_read_error(const std::string& content);

/// Entries `.<name>.pcdp-*` beside the output folder `parent/name` (staging, aside, lock): what a
/// commit must not leave behind.
std::vector<std::string> commit_leftovers(const std::string& parent, const std::string& name);

/// Column `name` of a PCD table as doubles.
std::vector<double> column(const io::PcdTable& t, const std::string& name);

double median(std::vector<double> v);

/// A pass of one scan line: the given ranges and amplitudes, bearings 0.01 rad apart, nod 0,
/// registered with an identity pose and default sensor.
Pass line_pass(const std::vector<float>& ranges, const std::vector<float>& amps);

/// Stage `type` made from a pipeline `register` -> `type`, read from YAML by the real loader
/// (inputs unchecked): `sensor` is the sensor block's flow mapping ("" for none), `options` the
/// stage's option lines (each "key: value"). Throws the loader's or the stage's ConfigError.
std::unique_ptr<Stage> stage_from_yaml(const std::string& type, const std::vector<std::string>& options,
                                       const std::string& sensor = "");

}  // namespace pcdp::test

/// Skips a test that limits the address space (RLIMIT_AS): AddressSanitizer's shadow memory needs
/// more address space than any such limit, so under it the limit measures nothing.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define PCDP_SKIP_IF_ADDRESS_SPACE_IS_SANITIZED() \
  GTEST_SKIP() << "address-space limits do not apply under a sanitizer's shadow memory"
#else
#define PCDP_SKIP_IF_ADDRESS_SPACE_IS_SANITIZED() (void)0
#endif
