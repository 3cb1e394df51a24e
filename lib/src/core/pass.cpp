#include "pcdp/core/pass.hpp"

#include <algorithm>
#include <stdexcept>

namespace pcdp {

std::size_t Pass::kept() const {
  return static_cast<std::size_t>(std::count(label.begin(), label.end(), Label::kKept));
}

Pass lines_of(const Pass& p, std::size_t from, std::size_t to) {
  if (from > to || to > p.line_count()) throw std::out_of_range("lines_of: lines outside the pass");
  Pass w;
  w.index = p.index;
  w.source = p.source;
  w.organized = p.organized;
  if (p.line_begin.empty()) return w;  // no lines: nothing to cut
  const std::size_t b = p.line_begin[from], e = p.line_begin[to], n = p.size();
  // A column is cut where it has one value per return (a stage may not have derived it yet).
  const auto cut = [&](const auto& src, auto& dst, std::size_t per = 1) {
    if (src.size() == per * n)
      dst.assign(src.begin() + static_cast<long>(per * b), src.begin() + static_cast<long>(per * e));
  };
  cut(p.line, w.line);
  cut(p.beam, w.beam);
  cut(p.range, w.range);
  cut(p.bearing, w.bearing);
  cut(p.amplitude, w.amplitude);
  cut(p.nod, w.nod);
  cut(p.stamp, w.stamp);
  for (const ExtraField& x : p.extra) {
    if (x.data.size() != x.field.bytes() * n)
      throw std::logic_error("lines_of: extra field '" + x.field.name + "' does not hold one value per return");
    ExtraField c{x.field, {}};
    cut(x.data, c.data, x.field.bytes());
    w.extra.push_back(std::move(c));
  }
  cut(p.label, w.label);
  cut(p.flags, w.flags);
  cut(p.range_cal, w.range_cal);
  cut(p.nod_at_return, w.nod_at_return);
  cut(p.x, w.x);
  cut(p.y, w.y);
  cut(p.z, w.z);
  cut(p.ox, w.ox);
  cut(p.oy, w.oy);
  cut(p.oz, w.oz);
  cut(p.cov, w.cov, 6);
  for (std::size_t k = from; k <= to; ++k) w.line_begin.push_back(p.line_begin[k] - b);
  return w;
}

}  // namespace pcdp
