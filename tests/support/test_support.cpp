#include "test_support.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "pcdp/core/errors.hpp"
#include "pcdp/core/pass.hpp"
#include "pcdp/io/pass_file.hpp"
#include "pcdp/pipeline/config.hpp"
#include "pcdp/stages/register.hpp"
#include "pcdp_test_paths.hpp"

namespace fs = std::filesystem;

namespace pcdp::test {

std::string fresh_dir(const std::string& tag) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "test";
  if (!tag.empty()) name += "." + tag;
  std::replace(name.begin(), name.end(), '/', '_');
  const fs::path p = fs::path(PCDP_TEST_TMP_DIR) / name;
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

namespace {
std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}
}  // namespace

CliResult run_cli(const std::vector<std::string>& args, const std::string& cwd) {
  const std::string dir = fresh_dir("cli");
  const std::string out = dir + "/stdout", err = dir + "/stderr";
  std::string cmd = (cwd.empty() ? "" : "cd " + quote(cwd) + " && ") + quote(PCDP_CLI_PATH);
  for (const auto& a : args) cmd += " " + quote(a);
  cmd += " >" + quote(out) + " 2>" + quote(err) + " </dev/null";
  const int status = std::system(cmd.c_str());
  CliResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = read_text(out);
  r.err = read_text(err);
  return r;
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
}

std::string pass_read_error(const std::string& content) {
  const std::string path = fresh_dir("read") + "/p.pcd";
  write_text(path, content);
  try {
    read_pass(path, 0);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

std::vector<std::string> commit_leftovers(const std::string& parent, const std::string& name) {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(parent)) {
    const std::string n = e.path().filename().string();
    if (n.rfind("." + name + ".pcdp-", 0) == 0) out.push_back(n);
  }
  return out;
}

std::vector<std::string> prepare_args(const std::string& yaml, const std::string& out_dir) {
  std::ifstream in(yaml);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("# prepare: ", 0) != 0) continue;
    std::istringstream is(line.substr(11));
    std::vector<std::string> args;
    for (std::string a; is >> a;) {
      if (a.rfind("${SHARED}", 0) == 0) a = std::string(PCDP_SHARED_DIR) + a.substr(9);
      args.push_back(a);
    }
    for (std::size_t i = 0; i + 1 < args.size(); ++i)
      if (args[i] == "--output-dir") args[i + 1] = out_dir;
    return args;
  }
  return {};
}

std::string read_text(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

sim::SimConfig small_sim_config() {
  sim::SimConfig c;
  c.scanner.beams = 91;
  c.scanner.nod_rate = 1.2;  // rad/s: 16 mrad over one 13.3 ms line, so skew matters
  c.scanner.nod_min = -0.45;
  c.scanner.nod_max = 0.05;
  c.scene.undulation_amplitude = 0.15;
  c.scene.undulation_wavelength = 8.0;
  c.scene.boxes.push_back({{6.0, -1.0, 0.0}, {7.0, 1.0, 1.2}, 0.8});
  c.motion.speed = 1.5;
  c.motion.yaw_rate = 0.05;
  c.motion.roll_amplitude = 0.03;
  c.motion.pitch_amplitude = 0.02;
  c.motion.start = {0.0, 0.0, 0.4};
  c.mount_translation = {0.4, 0.0, 1.2};
  c.mount_rpy = {0.01, 0.19775, -0.02};
  c.passes = 2;
  c.lines_per_pass = 60;
  c.t0 = 100.0;
  return c;
}

std::string pipeline_yaml(const sim::SimConfig& cfg, const std::string& dir, const std::string& out_dir,
                          const std::string& extra_register_options) {
  std::ostringstream y;
  y.precision(17);
  y << "rpy_order: " << rpy_order_name(cfg.rpy_order) << "\n"
    << "input:\n  scans: " << dir << "/pass_*.pcd\n  poses: " << dir << "/poses.csv\n"
    << "output_dir: " << out_dir << "\n"
    << "mount: {x: " << cfg.mount_translation.x() << ", y: " << cfg.mount_translation.y()
    << ", z: " << cfg.mount_translation.z() << ", roll: " << cfg.mount_rpy.roll << ", pitch: " << cfg.mount_rpy.pitch
    << ", yaw: " << cfg.mount_rpy.yaw << "}\n"
    << "sensor:\n  range_min: 0.1\n  range_max: " << cfg.scanner.range_max << "\n"
    << "  encoder_resolution: " << cfg.scanner.encoder_resolution << "\n"
    << "stages:\n  - type: register\n" << extra_register_options;
  return y.str();
}

std::vector<double> column(const io::PcdTable& t, const std::string& name) {
  const int k = t.header.field_index(name);
  EXPECT_GE(k, 0) << "no field " << name;
  if (k < 0) return {};
  return io::column_values(t, static_cast<std::size_t>(k));
}

double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

Pass line_pass(const std::vector<float>& ranges, const std::vector<float>& amps) {
  Pass p;
  const std::size_t n = ranges.size();
  for (std::size_t i = 0; i < n; ++i) {
    p.line.push_back(0);
    p.beam.push_back(static_cast<std::uint32_t>(i));
    p.range.push_back(ranges[i]);
    p.bearing.push_back(0.01f * static_cast<float>(i));
    p.amplitude.push_back(amps[i]);
    p.nod.push_back(0.0f);
    p.stamp.push_back(1e-4 * static_cast<double>(i));
  }
  p.line_begin = {0, n};
  p.label.assign(n, Label::kKept);
  p.flags.assign(n, 0);
  register_pass(p, RegisterParams{}, SensorParams{}, Eigen::Isometry3d::Identity(), nullptr);
  return p;
}

std::unique_ptr<Stage> stage_from_yaml(const std::string& type, const std::vector<std::string>& options,
                                       const std::string& sensor) {
  std::string yaml = "input: {scans: x.pcd}\noutput_dir: out\n";
  if (!sensor.empty()) yaml += "sensor: " + sensor + "\n";
  yaml += "stages:\n  - type: register\n  - type: " + type + "\n";
  for (const auto& line : options) yaml += "    " + line + "\n";
  LoadOptions o;
  o.check_inputs = false;
  const PipelineConfig c = load_pipeline_from_string(yaml, "p.yaml", "/", o);
  return find_stage(type)->create(c.stages[1], RunContext{&c, nullptr});
}

}  // namespace pcdp::test
