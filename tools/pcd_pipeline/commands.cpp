#include "commands.hpp"

#include <unistd.h>

#include <cstdio>
#include <iostream>

#include "pcdp/config.hpp"
#include "pcdp/errors.hpp"
#include "pcdp/pipeline.hpp"
#include "pcdp/stage.hpp"

namespace pcdp::cli {

namespace {
LoadOptions load_options(const RunArgs& a) {
  LoadOptions o;
  for (const auto& s : a.sets) o.overrides.push_back(parse_override(s));
  o.output_dir = a.output_dir;
  return o;
}
}  // namespace

int cmd_validate(const RunArgs& a) {
  Pipeline p = Pipeline::prepare(load_pipeline(a.pipeline, load_options(a)));
  const PipelineConfig& c = p.config();
  if (!a.quiet) {
    std::cout << a.pipeline << ": valid: " << c.stages.size() << " stage(s) (";
    for (std::size_t i = 0; i < c.stages.size(); ++i) std::cout << (i ? " -> " : "") << c.stages[i].name;
    std::cout << "), " << c.scans.size() << " pass file(s), "
              << (c.poses.empty() ? std::string("no pose file (T_M_V = identity)") : "poses " + c.poses)
              << ", output_dir " << c.output_dir << "\n";
  }
  return 0;
}

int cmd_run(const RunArgs& a) {
  Pipeline p = Pipeline::prepare(load_pipeline(a.pipeline, load_options(a)));
  const bool tty = !a.quiet && ::isatty(STDERR_FILENO);
  ProgressFn progress;
  if (tty) {
    progress = [](const ProgressEvent& e) {
      std::fprintf(stderr, "\r\033[K[pass %zu/%zu] %s: %s", e.pass + 1, e.passes, e.file.c_str(), e.step.c_str());
      std::fflush(stderr);
    };
  }
  const RunSummary s = p.run(progress);
  if (tty) std::fprintf(stderr, "\r\033[K");
  if (!a.quiet) {
    std::cout << "pcd_pipeline: " << s.passes.size() << " pass(es), " << s.input_returns << " returns, "
              << s.labels[0] << " kept, in " << s.seconds << " s\n";
    std::cout << "labels:";
    for (std::size_t l = 0; l < kLabelCount; ++l)
      if (s.labels[l]) std::cout << " " << label_name(static_cast<Label>(l)) << "=" << s.labels[l];
    std::cout << "\n";
    for (const auto& st : s.stages)
      std::cout << "  " << st.name << " (" << st.type << "): " << st.in << " -> " << st.out << " kept, "
                << st.seconds << " s\n";
    for (const auto& w : s.warnings) std::cout << "warning: " << w << "\n";
    std::cout << "outputs in " << s.output_dir << ":";
    for (const auto& o : s.outputs) std::cout << " " << o.substr(o.find_last_of('/') + 1);
    std::cout << "\n";
  }
  return 0;
}

int cmd_stages() {
  for (const auto& s : builtin_stages()) std::cout << s.type << "\t" << s.summary << "\n";
  return 0;
}

int cmd_describe(const std::string& what) {
  if (what == "sensor" || what == "mount" || what == "pose_sigma") {
    const OptionSchema& sch = what == "sensor" ? sensor_schema() : what == "mount" ? mount_schema() : pose_sigma_schema();
    std::cout << what << " block\n\n" << describe_schema(sch);
    return 0;
  }
  const StageInfo* info = find_stage(what);
  if (!info) {
    auto names = stage_type_names();
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
    names.insert(names.end(), {"sensor", "mount", "pose_sigma"});
    throw ConfigError("describe: unknown stage '" + what + "'" + did_you_mean(what, names) + "; stages: " + list +
                      "; blocks: sensor, mount, pose_sigma");
  }
  std::cout << info->type << ": " << info->summary << "\n\n" << describe_schema(info->schema);
  return 0;
}

}  // namespace pcdp::cli
