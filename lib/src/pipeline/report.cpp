// report.json: what a run read, did and wrote (docs/data_contract.md, "report.json").
#include <string>

#include <nlohmann/json.hpp>

#include "pcdp/core/errors.hpp"
#include "pcdp/core/labels.hpp"
#include "pcdp/pipeline/pipeline.hpp"

#ifndef PCDP_VERSION
#define PCDP_VERSION "unknown"
#endif

namespace pcdp {

namespace {
nlohmann::json values_json(const OptionValues& v) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [name, val] : v.all()) {
    nlohmann::json x;
    if (std::holds_alternative<bool>(val)) x = std::get<bool>(val);
    else if (std::holds_alternative<std::int64_t>(val)) x = std::get<std::int64_t>(val);
    else if (std::holds_alternative<double>(val)) x = std::get<double>(val);
    else x = std::get<std::string>(val);
    // Dotted keys become nested objects again, as the user wrote them.
    nlohmann::json* cur = &j;
    std::string key = name;
    for (auto dot = key.find('.'); dot != std::string::npos; dot = key.find('.')) {
      cur = &(*cur)[key.substr(0, dot)];
      key = key.substr(dot + 1);
    }
    (*cur)[key] = x;
  }
  return j;
}

nlohmann::json labels_json(const LabelHistogram& h) {
  nlohmann::json j = nlohmann::json::object();
  for (std::size_t l = 0; l < kLabelCount; ++l) j[label_name(static_cast<Label>(l))] = h[l];
  return j;
}

/// The label code table (docs/data_contract.md "Labels"): what the `label` field of returns.pcd holds.
nlohmann::json label_codes_json() {
  nlohmann::json j = nlohmann::json::array();
  for (std::size_t l = 0; l < kLabelCount; ++l)
    j.push_back({{"code", l}, {"name", label_name(static_cast<Label>(l))}, {"meaning", label_meaning(static_cast<Label>(l))}});
  return j;
}

/// The unit of every field of the products (returns.pcd, cloud.pcd, elevation.tif's bands) and of
/// the report's own numbers. The options' units: `pcd_pipeline describe <stage or block>`.
nlohmann::json units_json() {
  return {{"x", "m"},
          {"y", "m"},
          {"z", "m"},
          {"range", "m"},
          {"amplitude", "sensor units"},
          {"intensity", "sensor units (the amplitude)"},
          {"pass", "index (0-based, into config.input.scans)"},
          {"line", "index"},
          {"beam", "index"},
          {"label", "code (label_codes)"},
          {"flags", "bit set"},
          {"stamp", "s"},
          {"cov_xx", "m^2"},
          {"cov_xy", "m^2"},
          {"cov_xz", "m^2"},
          {"cov_yy", "m^2"},
          {"cov_yz", "m^2"},
          {"cov_zz", "m^2"},
          {"sigma_h", "m"},
          {"elevation", "m"},
          {"variance", "m^2"},
          {"count", "returns"},
          {"passes", "passes"},
          {"min", "m"},
          {"max", "m"},
          {"map_origin", "m"},
          {"seconds", "s"},
          {"cpu_seconds", "s"},
          {"bytes", "bytes"}};
}

nlohmann::json files_json(const std::vector<RunSummary::FileRecord>& files) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& f : files) {
    nlohmann::json e = {{"file", f.file}, {"bytes", f.bytes}, {"sha256", f.sha256}};
    if (!f.kind.empty()) e["kind"] = f.kind;
    j.push_back(e);
  }
  return j;
}
}  // namespace

std::string report_json(const PipelineConfig& cfg, const RunSummary& sum) {
  nlohmann::json j;
  j["pcd_pipeline"] = {{"version", PCDP_VERSION},
                       {"eigen", std::to_string(EIGEN_WORLD_VERSION) + "." + std::to_string(EIGEN_MAJOR_VERSION) +
                                     "." + std::to_string(EIGEN_MINOR_VERSION)}};
  j["started_at"] = sum.started_at;
  nlohmann::json c;
  c["pipeline_file"] = cfg.source;
  c["rpy_order"] = rpy_order_name(cfg.rpy_order);
  c["input"] = {{"scans", cfg.scans}, {"poses", cfg.poses}};
  c["output_dir"] = cfg.output_dir;
  c["allow_empty_output"] = cfg.allow_empty_output;
  c["crs"] = cfg.crs;  // "" without one
  for (const auto& [name, vals] : cfg.blocks) c[name] = values_json(vals);
  c["stages"] = nlohmann::json::array();
  for (const auto& sc : cfg.stages) {
    nlohmann::json s = values_json(sc.options);
    s["type"] = sc.type;
    s["name"] = sc.name;
    c["stages"].push_back(s);
  }
  j["config"] = c;
  j["input_returns"] = sum.input_returns;
  j["kept"] = sum.labels[0];
  j["labels"] = labels_json(sum.labels);
  j["label_codes"] = label_codes_json();
  j["units"] = units_json();
  j["inputs"] = files_json(sum.input_files);
  j["outputs"] = files_json(sum.output_files);
  j["passes"] = nlohmann::json::array();
  for (const auto& p : sum.passes)
    j["passes"].push_back({{"file", p.file}, {"returns", p.returns}, {"lines", p.lines}, {"kept", p.kept}});
  j["stages"] = nlohmann::json::array();
  for (const auto& r : sum.stages) {
    nlohmann::json rejected = nlohmann::json::object();
    for (std::size_t l = 1; l < kLabelCount; ++l)
      if (r.rejected[l]) rejected[label_name(static_cast<Label>(l))] = r.rejected[l];
    j["stages"].push_back({{"name", r.name},
                           {"type", r.type},
                           {"in", r.in},
                           {"out", r.out},
                           {"rejected", rejected},
                           {"seconds", r.seconds},
                           {"metrics", r.metrics},
                           {"warnings", r.warnings}});
  }
  j["warnings"] = sum.warnings;
  j["seconds"] = sum.seconds;
  j["phases"] = nlohmann::json::array();
  for (const auto& ph : sum.phases)
    j["phases"].push_back({{"phase", ph.name}, {"seconds", ph.seconds}, {"cpu_seconds", ph.cpu_seconds}});
  j["threads"] = sum.threads;
  if (!sum.map_origin.isZero()) j["map_origin"] = {sum.map_origin.x(), sum.map_origin.y(), sum.map_origin.z()};
  // Paths are bytes on Linux: a file name that is not UTF-8 (matched by a glob, or given with
  // --output-dir or --set) is written with U+FFFD in place of its invalid bytes, never a failure.
  return j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

}  // namespace pcdp
