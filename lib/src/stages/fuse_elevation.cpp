#include "pcdp/stages/fuse_elevation.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pcdp/core/errors.hpp"
#include "pcdp/core/georef.hpp"
#include "pcdp/io/geotiff.hpp"
#include "pcdp/core/pass.hpp"

namespace pcdp {

namespace {
/// Reads p.extent ("xmin,ymin,xmax,ymax") into p.xmin .. p.ymax and p.has_extent. Returns nullopt
/// when it is empty or valid, else what is wrong ("" when only the order of the bounds is).
std::optional<std::string> read_extent(FuseElevationParams& p) {
  p.has_extent = false;
  if (p.extent.empty()) return std::nullopt;
  std::vector<double> v;
  if (const auto err = parse_number_list(p.extent, 4, v)) return "it " + *err;
  p.xmin = v[0], p.ymin = v[1], p.xmax = v[2], p.ymax = v[3];
  if (!(p.xmax > p.xmin) || !(p.ymax > p.ymin)) return std::string();
  p.has_extent = true;
  return std::nullopt;
}
}  // namespace

const Options<FuseElevationParams>& fuse_elevation_options() {
  using P = FuseElevationParams;
  static const auto o = Options<P>()
      .add("resolution", &P::resolution, bounds(0.001, 1000), "m", "cell size of the grid")
      .add("band", &P::band, bounds(0.001, 100), "m", "height band of the top-surface gate (points more than one band below the top band are not fused)")
      .add("min_support", &P::min_support, bounds(1, 1000), "points", "the surface is the highest height band with at least this many points")
      .add("extent", &P::extent, "xmin,ymin,xmax,ymax in map metres; empty: the grid grows with the data")
      .add("z_max", &P::z_max, bounds(-1e9, 1e9), "m", "points higher than this (map z) are not fused: ceilings, overhangs, tree crowns")
      .add("png", &P::png, "also draw elevation.png")
      .add("deflate_level", &P::deflate_level, bounds(1, 12), "", "DEFLATE level of elevation.tif (libdeflate): 1 compresses fastest (2.3x level 6, GDAL's default, on the 8-pass bench grid; 2.4 % larger), 12 smallest")
      .rule("extent is empty or xmin,ymin,xmax,ymax with xmax > xmin and ymax > ymin",
            [](const P& p) {
              P q = p;
              return read_extent(q);
            },
            "a rectangle in map metres",
            "option 'extent' = '{extent}' must be xmin,ymin,xmax,ymax in metres with xmax > xmin and ymax > ymin");
  return o;
}

const OptionSchema& fuse_elevation_schema() { return fuse_elevation_options().schema(); }

namespace {
/// The points of a pass that go into the grid, with their vertical variance.
/// Points in map metres: the pass's coordinates plus the map origin (none added when it is 0, so
/// a run without an origin fuses the very same doubles). A point the grid cannot hold is an
/// InputError: fusing it would wrap its cell key onto another cell.
template <class F>
void for_each_point(const ElevationGrid& grid, const Pass& pass, const FuseElevationParams& p, double fallback_var, F&& f) {
  const bool cov = pass.cov.size() == 6 * pass.size();
  const bool shift = p.origin_x != 0.0 || p.origin_y != 0.0 || p.origin_z != 0.0;
  for (std::size_t i = 0; i < pass.size(); ++i) {
    if (!pass.is_kept(i) || !std::isfinite(pass.z[i])) continue;
    double x = pass.x[i], y = pass.y[i], z = pass.z[i];
    if (shift) {
      x += p.origin_x;
      y += p.origin_y;
      z += p.origin_z;
    }
    if (p.has_extent && (x < p.xmin || x >= p.xmax || y < p.ymin || y >= p.ymax)) continue;
    if (z > p.z_max) continue;
    if (!grid.holds_point(x, y, z))
      throw InputError(pass.source + ": line " + std::to_string(pass.line[i]) + " beam " + std::to_string(pass.beam[i]) +
                       ": stage " + p.stage + ": the point " + format_point(x, y, z) +
                       " (map metres) is beyond what the elevation grid holds: cells within 2^30 of its origin's (" +
                       format_value(static_cast<double>(ElevationGrid::kKeyReach) * grid.resolution()) + " m at resolution " +
                       format_value(grid.resolution()) + " m), height bands within 2^31 of 0 (" +
                       format_value(2147483648.0 * grid.band()) + " m at band " + format_value(grid.band()) +
                       " m); check the pose file's coordinates, or use a coarser 'resolution' / 'band'");
    double var = cov ? static_cast<double>(pass.cov[6 * i + 5]) : fallback_var;
    if (!(var > 1e-12)) var = fallback_var;
    f(x, y, z, var, static_cast<std::int32_t>(pass.index));
  }
}

/// Inclusive index bounds of cells (none yet: lo > hi).
struct CellBounds {
  std::int64_t lo[2] = {INT64_MAX, INT64_MAX}, hi[2] = {INT64_MIN, INT64_MIN};
  bool any() const { return lo[0] <= hi[0]; }
  void add(std::int64_t ix, std::int64_t iy) {
    lo[0] = std::min(lo[0], ix);
    lo[1] = std::min(lo[1], iy);
    hi[0] = std::max(hi[0], ix);
    hi[1] = std::max(hi[1], iy);
  }
  void add(const CellBounds& b) {
    if (!b.any()) return;
    add(b.lo[0], b.lo[1]);
    add(b.hi[0], b.hi[1]);
  }
};

/// The samples of the points of `pass` that go into `grid`, in the pass's order, and their cells' bounds.
std::vector<ElevationSample> samples(const ElevationGrid& grid, const Pass& pass, const FuseElevationParams& p,
                                     double fallback_var, CellBounds& bounds) {
  std::vector<ElevationSample> out;
  out.reserve(pass.size());
  for_each_point(grid, pass, p, fallback_var, [&](double x, double y, double z, double var, std::int32_t k) {
    out.push_back(grid.sample(x, y, z, var, k));
    bounds.add(grid.cell_index(x), grid.cell_index(y));
  });
  return out;
}
}  // namespace

ElevationGrid make_elevation_grid(const FuseElevationParams& p) {
  ElevationGrid g(p.resolution, p.band, p.min_support);
  if (p.origin_x != 0.0 || p.origin_y != 0.0) g.set_key_origin(g.cell_index(p.origin_x), g.cell_index(p.origin_y));
  return g;
}

void fuse_pass(ElevationGrid& grid, const Pass& pass, const FuseElevationParams& p, double fallback_var) {
  // In slices through a small buffer: no array the size of the pass to allocate (and fault in).
  std::array<ElevationSample, 256> buf;
  std::size_t n = 0;
  for_each_point(grid, pass, p, fallback_var, [&](double x, double y, double z, double var, std::int32_t k) {
    buf[n++] = grid.sample(x, y, z, var, k);
    if (n == buf.size()) {
      grid.add(buf.data(), n);
      n = 0;
    }
  });
  grid.add(buf.data(), n);
}

namespace {
class FuseElevationStage final : public Stage {
 public:
  FuseElevationStage(FuseElevationParams p, double fallback_var, std::string name, std::string crs)
      : Stage(p.png ? std::vector<std::string>{"elevation.tif", "elevation.state.tif", "elevation.png"}
                    : std::vector<std::string>{"elevation.tif", "elevation.state.tif"}),  // the merge state beside the grid
        params_(p), fallback_var_(fallback_var), name_(std::move(name)), crs_(std::move(crs)),
        key_grid_(make_elevation_grid(p)) {}
  StageKind kind() const override { return StageKind::kAccumulator; }
  // The samples a pass adds, computed on the worker (copied, since later stages may still change
  // the pass); the fold only looks their cells up and sums, in pass order.
  std::unique_ptr<Partial> collect(const Pass& pass, StageReport&, WorkShare&) const override {
    Samples w;
    w.samples = samples(key_grid_, pass, params_, fallback_var_, w.bounds);
    w.source = pass.source;
    return Fused::of(std::move(w), pass.index == 0, [this] { return fresh(); },
                     [this](State& s, Samples&& x) { fold(s, std::move(x)); });
  }
  // The cells' sums and top height bands depend on the order of the samples: the partial folds
  // in pass order (InOrderPartial), exactly what adding pass by pass gives.
  void merge(Partial& into, Partial&& later) const override {
    static_cast<Fused&>(into).absorb(std::move(static_cast<Fused&>(later)),
                                     [this](State& s, Samples&& x) { fold(s, std::move(x)); });
  }
  // Two writers, run at once when the run has threads: elevation.tif and its merge state (and the
  // report's cell counts), then elevation.png. Both only read the grid.
  std::vector<ProductWriter> finish(std::unique_ptr<Partial> all, StageReport&, unsigned) override {
    std::unique_ptr<State> s = Fused::fold_all(all.get(), [this] { return fresh(); },
                                               [this](State& st, Samples&& x) { fold(st, std::move(x)); });
    auto grid = std::make_shared<const ElevationGrid>(std::move(s->grid));
    std::vector<ProductWriter> w;
    w.push_back({{"elevation.tif", "elevation.state.tif"},
                 [this, grid](const std::vector<std::string>& to, StageReport& report, WorkShare& share) {
                   named([&] { write_grid(*grid, to[0], to[1], report, share); });
                 }});
    if (params_.png)
      w.push_back({{"elevation.png"}, [this, grid](const std::vector<std::string>& to, StageReport& report, WorkShare&) {
                     named([&] {
                       const auto t0 = std::chrono::steady_clock::now();
                       const int down = io::write_elevation_png(*grid, to[0]);
                       if (down > 1) report.metrics["png_cells_per_pixel"] = static_cast<double>(down * down);
                       report.metrics["write_seconds"] +=
                           std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
                     });
                   }});
    return w;
  }

 private:
  struct State {
    ElevationGrid grid;
    CellBounds bounds;
  };
  struct Samples {
    std::vector<ElevationSample> samples;
    CellBounds bounds;
    std::string source;
    friend void save_item(std::ostream& o, const Samples& w) {
      partial_io::put_str(o, "fuse_elevation.samples");
      partial_io::put_vec(o, w.samples);
      partial_io::put(o, w.bounds);
      partial_io::put_str(o, w.source);
    }
    friend void load_item(std::istream& i, Samples& w) {
      partial_io::expect(i, "fuse_elevation.samples");
      partial_io::get_vec(i, w.samples);
      partial_io::get(i, w.bounds);
      w.source = partial_io::get_str(i);
    }
  };
  using Fused = InOrderPartial<State, Samples>;
  std::unique_ptr<State> fresh() const { return std::make_unique<State>(State{make_elevation_grid(params_), {}}); }

  void fold(State& s, Samples&& w) const {
    check_extent(s.bounds, w.bounds, w.source, s.grid.resolution());
    s.grid.add(w.samples.data(), w.samples.size());
  }

  // A grid too large for its product: name the stage.
  template <class F>
  void named(F&& f) const {
    try {
      f();
    } catch (const InputError& e) {
      throw InputError("stage '" + name_ + "' (fuse_elevation): " + e.what());
    }
  }

  void write_grid(const ElevationGrid& grid, const std::string& tif, const std::string& state, StageReport& report,
                  WorkShare& share) const {
    const auto t0 = std::chrono::steady_clock::now();
    const std::size_t cells = io::write_elevation_geotiff(grid, tif, params_.deflate_level, share, crs_, state);
    report.metrics["write_seconds"] += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    report.metrics["cells"] = static_cast<double>(cells);
    // A grid without one surface is no map: say so (report.json and stderr) rather than leave an
    // all-NaN elevation band to be found in a GIS.
    std::size_t surfaces = 0;
    grid.for_each([&](std::int64_t, std::int64_t, const ElevationCell& c) {
      double w = 0.0, wz = 0.0;
      c.surface(params_.min_support, w, wz);
      surfaces += w > 0.0 ? 1 : 0;
    });
    report.metrics["surface_cells"] = static_cast<double>(surfaces);
    if (surfaces == 0)
      report.warnings.push_back("no cell of the elevation grid has a surface (" + std::to_string(cells) +
                                " cell(s) seen, none with min_support = " + std::to_string(params_.min_support) +
                                " points in one height band" + (params_.has_extent ? ", inside 'extent'" : "") +
                                "): elevation.tif holds no elevation");
  }

  /// The products' size limit (io::check_elevation_extent), checked as each pass is folded: a pose
  /// jump stops the run at the pass that made it, not after every pass was fused.
  void check_extent(CellBounds& bounds, const CellBounds& pass_bounds, const std::string& source, double res) const {
    CellBounds b = bounds;
    b.add(pass_bounds);
    if (!b.any()) return;
    try {
      io::check_elevation_extent(b.lo[0], b.lo[1], b.hi[0], b.hi[1], res);
    } catch (const InputError& e) {
      throw InputError("stage '" + name_ + "' (fuse_elevation): with pass " + source + ": " + e.what());
    }
    bounds = b;
  }

  FuseElevationParams params_;
  double fallback_var_;
  std::string name_;
  std::string crs_;  ///< the pipeline's `crs` (normalised), elevation.tif's GeoKeys
  ElevationGrid key_grid_;  ///< empty: only its cell geometry is used, by collect() on any thread
};
}  // namespace

StageInfo fuse_elevation_stage_info() {
  return {"fuse_elevation",
          "2.5-D elevation grid of the top surface, weighted by each point's vertical variance (elevation.tif, its merge "
          "state elevation.state.tif, .png)",
          fuse_elevation_schema(),
          [](const StageConfig& sc, const RunContext& ctx) -> std::unique_ptr<Stage> {
            FuseElevationParams p = fuse_elevation_options().bind(sc.options);
            read_extent(p);
            p.origin_x = ctx.map_origin.x();
            p.origin_y = ctx.map_origin.y();
            p.origin_z = ctx.map_origin.z();
            p.stage = "'" + sc.name + "' (fuse_elevation)";
            const double s = ctx.config->sensor.range_sigma;
            return std::make_unique<FuseElevationStage>(p, s > 0 ? s * s : 1e-4, sc.name, ctx.config->crs);
          }};
}

}  // namespace pcdp
