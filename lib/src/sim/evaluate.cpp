#include "pcdp/sim/evaluate.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unordered_map>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/file_digest.hpp"
#include "pcdp/io/geotiff.hpp"
#include "pcdp/io/pcd.hpp"

namespace fs = std::filesystem;

namespace pcdp {

namespace {
std::vector<double> col(const io::PcdTable& t, const std::string& name, const std::string& file) {
  const int k = t.header.field_index(name);
  if (k < 0) throw InputError(file + ": missing field '" + name + "' needed by evaluate");
  return io::column_values(t, static_cast<std::size_t>(k));
}

/// Returns are matched by (line, beam): line indices are unique within a simulated run, so a
/// run over a subset of its passes (whose pass indices restart at 0) matches too.
std::uint64_t key(double line, double beam) {
  return (static_cast<std::uint64_t>(line) << 20) ^ static_cast<std::uint64_t>(beam);
}

bool is_filter_label(Label l) {
  return l == Label::kOcclusion || l == Label::kMixedPixel || l == Label::kOutlier || l == Label::kLowAmplitude ||
         l == Label::kInconsistent;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const std::size_t i = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(i), v.end());
  return v[i];
}
/// The run must have read this simulation's scans: report.json lists its inputs with their
/// SHA-256, and a run of another simulation with the same scanner would otherwise be scored
/// against the wrong truth without a word. A report without the list (an older version's) checks
/// nothing.
void require_run_of_these_scans(const std::string& truth_dir, const std::string& run_dir) {
  const fs::path report = fs::path(run_dir) / "report.json";
  std::error_code ec;
  if (!fs::is_regular_file(report, ec)) return;
  std::vector<std::string> run_scans;
  try {
    std::ifstream in(report);
    const auto j = nlohmann::json::parse(in);
    for (const auto& f : j.at("inputs"))
      if (f.value("kind", "") == "scan") run_scans.push_back(f.at("sha256").get<std::string>());
  } catch (const std::exception&) {
    return;
  }
  if (run_scans.empty()) return;
  std::size_t ours = 0, scans = 0;
  for (const auto& e : fs::directory_iterator(truth_dir, ec)) {
    const std::string n = e.path().filename().string();
    if (n.rfind("pass_", 0) != 0 || e.path().extension() != ".pcd") continue;
    ++scans;
    io::FileDigest d;
    if (io::digest_file(e.path().string(), d) == 0 && std::count(run_scans.begin(), run_scans.end(), d.sha256)) ++ours;
  }
  if (scans > 0 && ours == 0)
    throw InputError(run_dir + ": the run read none of the " + std::to_string(scans) + " scans of " + truth_dir +
                     " (report.json's inputs and the scans' SHA-256 differ): evaluate it against the simulation "
                     "its scans came from");
}
}  // namespace

Evaluation evaluate_run(const std::string& truth_dir, const std::string& run_dir, const NoiseModel& noise) {
  struct Truth {
    double x, y, z;
    Label label;
  };
  std::unordered_map<std::uint64_t, Truth> truth;
  const fs::path tdir = fs::path(truth_dir) / "truth";
  if (!fs::is_directory(tdir)) throw InputError(truth_dir + ": no truth/ folder (is this a `simulate` output?)");
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(tdir))
    if (e.path().filename().string().rfind("pass_", 0) == 0 && e.path().extension() == ".pcd") files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  if (files.empty()) throw InputError(tdir.string() + ": no truth pass files (pass_*.pcd)");
  for (std::size_t k = 0; k < files.size(); ++k) {
    const io::PcdTable t = io::read_pcd(files[k]);
    const auto line = col(t, "line", files[k]), beam = col(t, "beam", files[k]), x = col(t, "x", files[k]),
               y = col(t, "y", files[k]), z = col(t, "z", files[k]), label = col(t, "label", files[k]);
    for (std::size_t i = 0; i < line.size(); ++i)
      truth[key(line[i], beam[i])] = {x[i], y[i], z[i], static_cast<Label>(label[i])};
  }

  require_run_of_these_scans(truth_dir, run_dir);
  const std::string rfile = (fs::path(run_dir) / "returns.pcd").string();
  const io::PcdTable r = io::read_pcd(rfile);
  const auto pass = col(r, "pass", rfile), line = col(r, "line", rfile), beam = col(r, "beam", rfile),
             label = col(r, "label", rfile), range = col(r, "range", rfile);
  auto x = col(r, "x", rfile), y = col(r, "y", rfile), z = col(r, "z", rfile);
  // A georeferenced run stores x y z relative to its map origin (the header's "# map_origin").
  const double* vp = r.header.map_origin;
  if (vp[0] != 0.0 || vp[1] != 0.0 || vp[2] != 0.0)
    for (std::size_t i = 0; i < x.size(); ++i) {
      x[i] += vp[0];
      y[i] += vp[1];
      z[i] += vp[2];
    }

  Evaluation e;
  e.returns = r.header.points;
  const char* scored[] = {"occlusion", "mixed_pixel", "low_amplitude"};
  for (const char* s : scored) e.by_label[s] = {};
  std::vector<double> err, implied;
  for (std::size_t i = 0; i < pass.size(); ++i) {
    const auto it = truth.find(key(line[i], beam[i]));
    if (it == truth.end())
      throw InputError(rfile + ": pass " + std::to_string(static_cast<int>(pass[i])) + " line " +
                       std::to_string(static_cast<long>(line[i])) + " beam " + std::to_string(static_cast<int>(beam[i])) +
                       " has no truth (a run of a different simulation?)");
    const Truth& t = it->second;
    const Label rl = static_cast<Label>(label[i]);
    ++e.truth[static_cast<std::size_t>(t.label)];
    ++e.run[static_cast<std::size_t>(rl)];
    for (auto& [name, score] : e.by_label) {
      const Label l = label_from_name(name);
      if (t.label == l) {
        ++score.truth;
        score.rejected += rl != Label::kKept;
        score.same_label += rl == l;
      }
      score.run_labelled += rl == l;
    }
    if (t.label != Label::kKept || rl == Label::kNoPose || rl == Label::kOutOfRange) continue;
    ++e.valid;
    if (is_filter_label(rl)) ++e.valid_wrongly_rejected;
    if (rl != Label::kKept) continue;
    const double d = std::sqrt((x[i] - t.x) * (x[i] - t.x) + (y[i] - t.y) * (y[i] - t.y) + (z[i] - t.z) * (z[i] - t.z));
    err.push_back(d);
    if (noise.known) {
      // First-order error the noise sources imply at this range: range along the beam, position
      // on three axes (two interpolated samples average to 2/3 of the variance), pitch and yaw
      // across the beam (roll about a forward axis moves little), encoder quantization
      // (uniform, q^2 / 12) across the beam.
      const double rr = range[i];
      const double var = noise.range_sigma * noise.range_sigma + 2.0 * noise.position_sigma * noise.position_sigma +
                         2.0 * rr * rr * noise.rpy_sigma * noise.rpy_sigma +
                         rr * rr * noise.encoder_resolution * noise.encoder_resolution / 12.0;
      implied.push_back(std::sqrt(var));
    }
  }
  e.compared = err.size();
  e.error_median = quantile(err, 0.5);
  e.error_p95 = quantile(err, 0.95);
  double ss = 0;
  for (double v : err) ss += v * v;
  e.error_rms = err.empty() ? 0.0 : std::sqrt(ss / static_cast<double>(err.size()));
  e.implied_median = quantile(implied, 0.5);

  // Elevation against the true top surface: RMSE over observed cells away from the edges of the
  // true surface (where the true height changes by more than 5 cm to a neighbouring cell).
  const std::string etif = (fs::path(run_dir) / "elevation.tif").string(), th = (tdir / "height.pcd").string();
  if (fs::exists(etif) && fs::exists(th)) {
    const ElevationGrid grid = io::read_elevation_geotiff(etif);
    const io::PcdTable t = io::read_pcd(th);
    const auto tx = col(t, "x", th), ty = col(t, "y", th), tz = col(t, "z", th);
    std::unordered_map<std::uint64_t, double> truth_z;
    const auto k2 = [](std::int64_t ix, std::int64_t iy) {
      return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(ix)) << 32) | static_cast<std::uint32_t>(iy);
    };
    for (std::size_t i = 0; i < tx.size(); ++i) truth_z[k2(grid.cell_index(tx[i]), grid.cell_index(ty[i]))] = tz[i];
    e.has_elevation = true;
    double se = 0, sb = 0;
    std::vector<double> absd;
    for (std::size_t i = 0; i < tx.size(); ++i) {
      const std::int64_t ix = grid.cell_index(tx[i]), iy = grid.cell_index(ty[i]);
      ++e.truth_cells;
      const ElevationCell* c = grid.find(ix, iy);
      double elev = 0, var = 0;
      if (!c || !grid.surface(*c, elev, var)) continue;
      ++e.observed_cells;
      // The highest and lowest true height over the cell and its 8 neighbours: the cell is off the
      // true surface when it lies more than kOffTheSurface above the one or below the other (a cell
      // beside an edge may hold points of either side), and at an edge of the true surface (not
      // scored) when a neighbour is missing or differs from its own height by more than 5 cm.
      double hi = tz[i], lo = tz[i];
      bool edge = false;
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy) {
          const auto it = truth_z.find(k2(ix + dx, iy + dy));
          if (it == truth_z.end()) {
            edge = true;
            continue;
          }
          hi = std::max(hi, it->second);
          lo = std::min(lo, it->second);
        }
      e.cells_above += elev - hi > kOffTheSurface;
      e.cells_below += lo - elev > kOffTheSurface;
      edge = edge || hi - tz[i] > 0.05 || tz[i] - lo > 0.05;
      if (edge) continue;
      const double d = elev - tz[i];
      se += d * d;
      sb += d;
      absd.push_back(std::fabs(d));
      ++e.scored_cells;
    }
    if (e.scored_cells) {
      e.elevation_rmse = std::sqrt(se / static_cast<double>(e.scored_cells));
      e.elevation_bias = sb / static_cast<double>(e.scored_cells);
      e.elevation_abs_median = quantile(absd, 0.5);
      e.elevation_abs_p95 = quantile(absd, 0.95);
    }
  }
  return e;
}

std::string evaluation_table(const Evaluation& e) {
  std::ostringstream os;
  os << std::fixed;
  os << "returns: " << e.returns << "   truth:";
  for (std::size_t l = 0; l < kLabelCount; ++l)
    if (e.truth[l]) os << " " << label_name(static_cast<Label>(l)) << "=" << e.truth[l];
  os << "\n\n" << std::left << std::setw(16) << "truth label" << std::right << std::setw(8) << "count" << std::setw(10)
     << "recall" << std::setw(14) << "same label" << std::setw(12) << "precision" << "\n";
  for (const auto& [name, s] : e.by_label) {
    os << std::left << std::setw(16) << name << std::right << std::setw(8) << s.truth << std::setw(10) << std::setprecision(3)
       << s.recall() << std::setw(14) << s.same_label << std::setw(12) << s.precision() << "\n";
  }
  os << "\nvalid returns wrongly rejected: " << e.valid_wrongly_rejected << " of " << e.valid << " ("
     << std::setprecision(3) << 100.0 * e.valid_false_rejection() << " %)\n";
  os << "registration error of kept valid returns (" << e.compared << "): median " << std::setprecision(2)
     << e.error_median * 1000 << " mm, p95 " << e.error_p95 * 1000 << " mm, rms " << e.error_rms * 1000 << " mm";
  if (e.implied_median > 0) os << "; implied by the noise model: median " << e.implied_median * 1000 << " mm";
  os << "\n";
  if (e.has_elevation)
    os << "elevation: rmse " << std::setprecision(1) << e.elevation_rmse * 1000 << " mm (bias " << e.elevation_bias * 1000
       << " mm, |error| median " << e.elevation_abs_median * 1000 << " mm, p95 " << e.elevation_abs_p95 * 1000 << " mm) over " << e.scored_cells << " observed cells away from edges; coverage " << std::setprecision(3)
       << e.coverage() << " (" << e.observed_cells << " of " << e.truth_cells << " true cells); cells more than "
       << std::setprecision(1) << kOffTheSurface << " m above the true surface (phantom obstacles): " << e.cells_above
       << ", below it: " << e.cells_below << "\n";
  return os.str();
}

std::string evaluation_json(const Evaluation& e) {
  nlohmann::json j;
  j["returns"] = e.returns;
  for (std::size_t l = 0; l < kLabelCount; ++l) {
    j["truth_labels"][label_name(static_cast<Label>(l))] = e.truth[l];
    j["run_labels"][label_name(static_cast<Label>(l))] = e.run[l];
  }
  for (const auto& [name, s] : e.by_label)
    j["labels"][name] = {{"truth", s.truth}, {"rejected", s.rejected}, {"recall", s.recall()},
                         {"same_label", s.same_label}, {"run_labelled", s.run_labelled}, {"precision", s.precision()}};
  j["valid"] = {{"count", e.valid}, {"wrongly_rejected", e.valid_wrongly_rejected},
                {"false_rejection", e.valid_false_rejection()}};
  j["registration_error"] = {{"compared", e.compared}, {"median", e.error_median}, {"p95", e.error_p95},
                             {"rms", e.error_rms}, {"implied_median", e.implied_median}};
  if (e.has_elevation)
    j["elevation"] = {{"rmse", e.elevation_rmse}, {"bias", e.elevation_bias}, {"abs_median", e.elevation_abs_median},
                      {"abs_p95", e.elevation_abs_p95}, {"scored_cells", e.scored_cells},
                      {"observed_cells", e.observed_cells}, {"truth_cells", e.truth_cells}, {"coverage", e.coverage()},
                      {"cells_above_by_more_than_0_3_m", e.cells_above}, {"cells_below_by_more_than_0_3_m", e.cells_below}};
  return j.dump(2) + "\n";
}

}  // namespace pcdp
