#include "pcdp/models/line_recovery.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "pcdp/core/errors.hpp"

namespace pcdp {

namespace {
constexpr std::size_t kLinesPerScan = 1000000;  // scan k owns line numbers k * 1e6 ... (uint32: 4294 scans)
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double bearing_of(const Eigen::Vector3d& p) { return std::atan2(p.y(), std::hypot(p.x(), p.z())); }
double nod_of(const Eigen::Vector3d& p) { return std::atan2(p.z(), p.x()); }
/// The bearing of a point within the scan plane of nod `n`, over the full circle: a scanner that
/// sees a little past +-90 degrees (SICK: 180.x degree field) has points behind the nod axis there.
double plane_bearing(const Eigen::Vector3d& p, double n) {
  return std::atan2(p.y(), p.x() * std::cos(n) + p.z() * std::sin(n));
}
Eigen::Vector3d rebuild(double r, double b, double n) {
  return {r * std::cos(n) * std::cos(b), r * std::sin(b), r * std::sin(n) * std::cos(b)};
}

double median_of(std::vector<double> v) {
  if (v.empty()) return kNaN;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// The nod of a line: median over points away from the scan's ends (cos b > 0.3), else all.
double line_nod(const std::vector<Eigen::Vector3d>& line) {
  std::vector<double> inner, all;
  for (const auto& p : line) {
    if (!p.allFinite() || p.norm() <= 0) continue;
    all.push_back(nod_of(p));
    if (std::cos(bearing_of(p)) > 0.3) inner.push_back(nod_of(p));
  }
  return median_of(inner.empty() ? all : inner);
}

}  // namespace

std::vector<std::vector<Eigen::Vector3d>> split_lines(const std::vector<Eigen::Vector3d>& pts,
                                                      std::vector<std::size_t>* starts) {
  std::vector<std::vector<Eigen::Vector3d>> lines;
  double last = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const double b = bearing_of(pts[i]);
    if (lines.empty() || b < last - 0.5) {
      lines.emplace_back();
      if (starts) starts->push_back(i);
    }
    lines.back().push_back(pts[i]);
    last = b;
  }
  return lines;
}

Pass sensor_lines_to_pass(const std::vector<std::vector<Eigen::Vector3d>>& lines,
                          const std::vector<std::vector<float>>& intensity, std::size_t k, const std::string& source,
                          double max_residual, bool rows, LineRecovery& rec) {
  rec = LineRecovery{};
  std::vector<double> residuals;
  // Fit each line. Its points that do not rebuild within max_residual leave it and become lines of
  // their own (right after it), so no point moves by more than max_residual.
  struct Out {
    std::vector<Eigen::Vector3d> pts;
    std::vector<float> amp;
    double nod;
  };
  std::vector<Out> outs;
  for (std::size_t l = 0; l < lines.size(); ++l) {
    const auto& line = lines[l];
    const std::vector<float>* amp = intensity.size() == lines.size() ? &intensity[l] : nullptr;
    const double nod = line_nod(line);
    ++rec.lines;
    if (!std::isfinite(nod)) {  // a line of no-returns only
      outs.push_back({line, amp ? *amp : std::vector<float>{}, 0.0});
      continue;
    }
    Out fit{{}, {}, nod};
    std::vector<Out> loose;
    for (std::size_t i = 0; i < line.size(); ++i) {
      const auto& p = line[i];
      const float a = amp ? (*amp)[i] : std::numeric_limits<float>::quiet_NaN();
      if (p.allFinite() && p.norm() > 0) {
        const double e = (rebuild(p.norm(), plane_bearing(p, nod), nod) - p).norm();
        if (e > max_residual) {
          loose.push_back({{p}, {a}, nod_of(p)});
          continue;
        }
        residuals.push_back(e);
        rec.max_residual = std::max(rec.max_residual, e);
      }
      fit.pts.push_back(p);
      fit.amp.push_back(a);
    }
    if (!amp) fit.amp.clear();
    if (!loose.empty()) ++rec.split_lines;
    rec.loose_points += loose.size();
    if (!fit.pts.empty()) outs.push_back(std::move(fit));
    for (auto& o : loose) {
      if (!amp) o.amp.clear();
      outs.push_back(std::move(o));
    }
  }
  rec.median_residual = residuals.empty() ? 0.0 : median_of(residuals);
  if (outs.size() >= kLinesPerScan)
    throw InputError(source + ": " + std::to_string(outs.size()) + " scan lines; at most " +
                     std::to_string(kLinesPerScan - 1) + " per scan are supported (points that fit no line count one each)");
  // Beams: the column of an organized cloud, else the index on one bearing grid if every point
  // falls on it, else the position along the line.
  std::vector<double> steps;
  for (const auto& o : outs)
    for (std::size_t i = 1; i < o.pts.size(); ++i)
      if (o.pts[i].allFinite() && o.pts[i - 1].allFinite()) {
        const double d = plane_bearing(o.pts[i], o.nod) - plane_bearing(o.pts[i - 1], o.nod);
        if (d > 1e-6) steps.push_back(d);
      }
  const double step = median_of(steps);
  double bmin = std::numeric_limits<double>::infinity();
  for (const auto& o : outs)
    for (const auto& p : o.pts)
      if (p.allFinite() && p.norm() > 0) bmin = std::min(bmin, plane_bearing(p, o.nod));
  bool grid = !rows && std::isfinite(step) && rec.loose_points == 0;
  std::size_t width = 0;
  std::vector<std::vector<long>> beam_of(outs.size());
  for (std::size_t l = 0; grid && l < outs.size(); ++l) {
    std::vector<char> used;
    for (const auto& p : outs[l].pts) {
      const double g = (plane_bearing(p, outs[l].nod) - bmin) / step;
      const long b = std::lround(g);
      if (!p.allFinite() || std::fabs(g - static_cast<double>(b)) > 0.25 || b < 0 || b > 100000) {
        grid = false;
        break;
      }
      if (static_cast<std::size_t>(b) >= used.size()) used.resize(static_cast<std::size_t>(b) + 1, 0);
      if (used[static_cast<std::size_t>(b)]) {
        grid = false;
        break;
      }
      used[static_cast<std::size_t>(b)] = 1;
      beam_of[l].push_back(b);
      width = std::max(width, static_cast<std::size_t>(b) + 1);
    }
  }
  rec.organized = grid || (rows && rec.loose_points == 0);

  Pass p;
  p.index = k;
  p.source = source;
  p.organized = rec.organized;
  if (k >= 4294) throw InputError(source + ": at most 4294 scans can be imported at once (line numbers are 32-bit)");
  const double t0 = 1e5 * static_cast<double>(k);  // a scan may hold up to 1e6 lines of 13.3 ms
  const auto put = [&](std::size_t l, std::uint32_t beam, float range, double bearing, float amp, double nod, double frac) {
    p.line.push_back(static_cast<std::uint32_t>(k * kLinesPerScan + l));
    p.beam.push_back(beam);
    p.range.push_back(range);
    p.bearing.push_back(static_cast<float>(bearing));
    p.amplitude.push_back(amp);
    p.nod.push_back(static_cast<float>(nod));
    p.stamp.push_back(t0 + (static_cast<double>(l) + frac) * kScanLinePeriod);
  };
  const float nanf = std::numeric_limits<float>::quiet_NaN();
  for (std::size_t l = 0; l < outs.size(); ++l) {
    const Out& o = outs[l];
    p.line_begin.push_back(p.range.size());
    const auto amp_at = [&](std::size_t i) { return o.amp.size() == o.pts.size() ? o.amp[i] : nanf; };
    if (grid) {
      std::vector<long> slot(width, -1);
      for (std::size_t i = 0; i < o.pts.size(); ++i) slot[static_cast<std::size_t>(beam_of[l][i])] = static_cast<long>(i);
      for (std::size_t b = 0; b < width; ++b) {
        const double frac = (static_cast<double>(b) + 1.0) / static_cast<double>(width + 1);
        if (slot[b] < 0) {
          put(l, static_cast<std::uint32_t>(b), 0.0f, bmin + static_cast<double>(b) * step, nanf, o.nod, frac);
        } else {
          const auto& q = o.pts[static_cast<std::size_t>(slot[b])];
          put(l, static_cast<std::uint32_t>(b), static_cast<float>(q.norm()), plane_bearing(q, o.nod), amp_at(static_cast<std::size_t>(slot[b])), o.nod, frac);
        }
      }
    } else {
      double last_b = std::isfinite(bmin) ? bmin : 0.0;
      for (std::size_t i = 0; i < o.pts.size(); ++i) {
        const auto& q = o.pts[i];
        const bool ok = q.allFinite() && q.norm() > 0;
        const double b = ok ? plane_bearing(q, o.nod) : last_b;
        last_b = b;
        put(l, static_cast<std::uint32_t>(i), ok ? static_cast<float>(q.norm()) : 0.0f, b, ok ? amp_at(i) : nanf, o.nod,
            (static_cast<double>(i) + 1.0) / static_cast<double>(o.pts.size() + 1));
      }
    }
  }
  p.line_begin.push_back(p.range.size());
  p.label.assign(p.range.size(), Label::kKept);
  p.flags.assign(p.range.size(), 0);
  return p;
}

Eigen::Vector3d estimate_nod_origin(const std::vector<Eigen::Vector3d>& pts) {
  std::vector<Eigen::Vector3d> finite;
  for (const auto& p : pts)
    if (p.allFinite() && p.norm() > 0) finite.push_back(p);
  const auto cost = [&](const Eigen::Vector3d& o) {
    std::vector<Eigen::Vector3d> moved(finite.size());
    for (std::size_t i = 0; i < finite.size(); ++i) moved[i] = finite[i] - o;
    const auto lines = split_lines(moved);
    double sum = 0.0;
    std::size_t n = 0;
    for (std::size_t l = 0; l < lines.size(); l += 5) {
      const double nod = line_nod(lines[l]);
      if (!std::isfinite(nod)) continue;
      for (const auto& p : lines[l]) {
        sum += (rebuild(p.norm(), plane_bearing(p, nod), nod) - p).norm();
        ++n;
      }
    }
    return n ? sum / static_cast<double>(n) : std::numeric_limits<double>::infinity();
  };
  Eigen::Vector3d best = Eigen::Vector3d::Zero();
  double c = cost(best);
  for (double step = 0.25; step >= 0.001; step /= 2) {
    for (bool moved = true; moved;) {
      moved = false;
      for (const Eigen::Vector3d& d : {Eigen::Vector3d(step, 0, 0), Eigen::Vector3d(-step, 0, 0), Eigen::Vector3d(0, 0, step),
                                      Eigen::Vector3d(0, 0, -step)}) {
        const Eigen::Vector3d o = best + d;
        if (o.cwiseAbs().maxCoeff() > 1.0) continue;
        const double co = cost(o);
        if (co < c) {
          c = co;
          best = o;
          moved = true;
        }
      }
    }
  }
  return best;
}

}  // namespace pcdp
