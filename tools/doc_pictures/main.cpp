// Regenerates the pictures of docs/ that come from real data:
//   ./build/tools/pcdp_doc_pictures ../shared docs/img
// (Kept out of the CLI: it is documentation tooling, not a user command.)
// The other pictures of docs/img are the CLI's own products, copied:
//   sample_elevation.png        run pipelines/nodding_terrain.yaml  (its elevation.png)
//   kurt3d_elevation.png        run pipelines/kurt3d.yaml           (after its "# prepare:" line)
//   octomap_scan_elevation.png  run pipelines/octomap_scan.yaml     (after its "# prepare:" line)
//   error_budget.svg            error-budget pipelines/nodding_terrain.yaml --svg docs/img/error_budget.svg
//   amplitude_fig13_*.svg       amplitude-model (docs/occlusion.md)
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "pcdp/import/3dtk.hpp"
#include "pcdp/io/atomic_file.hpp"
#include "pcdp/io/svg_plot.hpp"
#include "pcdp/stages/reject_mixed_pixels.hpp"

using namespace pcdp;

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: pcdp_doc_pictures SHARED_DIR OUT_DIR\n");
    return 2;
  }
  const std::string shared = argv[1], out = argv[2];
  // Kurt3D scan000: mixed pixels removed by the cloud path of reject_mixed_pixels (clean-cloud).
  std::ifstream in(shared + "/datasets/kurt3d_3dtk_nodding/scan000.3d");
  if (!in) {
    std::fprintf(stderr, "cannot read %s/datasets/kurt3d_3dtk_nodding/scan000.3d\n", shared.c_str());
    return 3;
  }
  std::string header;
  std::getline(in, header);
  std::vector<Eigen::Vector3d> pts;
  for (double x, y, z; in >> x >> y >> z;) {
    const Eigen::Vector3d p(x / 100.0, y / 100.0, z / 100.0);
    if (p.norm() > 0.48 && p.norm() < 32.7) pts.push_back(p);
  }
  // The range image's elevation bands are about the scanner's z (up): our frame, not uos's y.
  std::vector<Eigen::Vector3d> ours(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) ours[i] = io::uos_to_ours(pts[i] * 100.0);
  const auto mixed = mixed_pixels_in_cloud(ours, Eigen::Vector3d::Zero(), {}, 0.0087, MixedPixelParams{}, 0.0053);  // as clean-cloud
  io::PlotSeries kept{"kept", {}, "#6b6b6b", false, true, 1.3}, removed{"mixed pixels removed", {}, "#d62728", false, true, 1.8};
  std::size_t n_removed = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const auto& p = pts[i];
    if (mixed[i]) ++n_removed;
    // Top view (uos frame: x right, z forward, y up) of a band between knee and head height.
    if (p.y() < 0.0 || p.y() > 1.2 || p.z() > 12.0) continue;
    if (mixed[i])
      removed.points.emplace_back(p.x(), p.z());
    else
      kept.points.emplace_back(p.x(), p.z());
  }
  io::PlotSpec spec;
  spec.title = "Kurt3D scan000 (real nodding SICK), top view 0-1.2 m above the floor: " + std::to_string(n_removed) + " of " +
               std::to_string(pts.size()) + " points removed";
  spec.xlabel = "x (m)";
  spec.ylabel = "z, forward (m)";
  spec.equal_axes = true;
  spec.series = {kept, removed};
  io::write_file_atomic(out + "/kurt3d_mixed_pixels.svg", io::svg_line_plot(spec, 900, 700));
  std::printf("written: %s/kurt3d_mixed_pixels.svg (%zu removed of %zu)\n", out.c_str(), n_removed, pts.size());
  return 0;
}
