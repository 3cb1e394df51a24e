#include "pcdp/io/pass_file.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cmath>
#include <cstring>
#include <new>
#include <numeric>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"

namespace pcdp {

namespace {

struct Required {
  const char* name;
  char type;
  int size;
  const char* meaning;
};
constexpr Required kRequired[] = {
    {"line", 'U', 4, "uint32 scan-line index"},  {"beam", 'U', 4, "uint32 return index within the line"},
    {"range", 'F', 4, "float32 range, m"},       {"bearing", 'F', 4, "float32 in-plane angle, rad"},
    {"amplitude", 'F', 4, "float32 amplitude"},  {"nod", 'F', 4, "float32 nod-encoder reading, rad"},
    {"stamp", 'F', 8, "float64 time, s"},
};

std::string type_text(const io::PcdField& f) {
  return std::string(1, f.type) + std::to_string(f.size) + (f.count != 1 ? " x" + std::to_string(f.count) : "");
}

template <typename T>
std::vector<T> column_as(const std::vector<std::uint8_t>& col, std::size_t n) {
  std::vector<T> v(n);
  if (n) std::memcpy(v.data(), col.data(), n * sizeof(T));
  return v;
}

template <typename T>
void permute(std::vector<T>& v, const std::vector<std::size_t>& order) {
  std::vector<T> out(v.size());
  for (std::size_t i = 0; i < order.size(); ++i) out[i] = v[order[i]];
  v.swap(out);
}

/// The indices of the required fields in `h`; throws InputError for a missing or mistyped one.
void required_fields(const io::PcdHeader& h, const std::string& source, int (&idx)[7]) {
  const auto fail = [&](const std::string& msg) -> void { throw InputError(source + ": " + msg); };
  for (int r = 0; r < 7; ++r) {
    const Required& req = kRequired[r];
    idx[r] = h.field_index(req.name);
    if (idx[r] < 0)
      fail(std::string("missing required field '") + req.name + "' (" + req.meaning +
           "); the data contract (docs/data_contract.md) needs line, beam, range, bearing, amplitude, nod, stamp");
    const io::PcdField& f = h.fields[static_cast<std::size_t>(idx[r])];
    if (f.type != req.type || f.size != req.size || f.count != 1)
      fail(std::string("field '") + req.name + "' has type " + type_text(f) + " but must be " +
           std::string(1, req.type) + std::to_string(req.size) + " (" + req.meaning + ")");
  }
}

}  // namespace

void check_pass_header(const std::string& path) {
  io::require_regular_file(path, "pass file");
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || ::access(path.c_str(), R_OK) != 0)
    throw InputError(path + ": cannot read the pass file (" + std::strerror(errno) + ")");
  const io::PcdHeader h = io::read_pcd_header(path);
  int idx[7];
  required_fields(h, path, idx);
  // The data a binary header claims must fit in the file (checked without overflow).
  const auto size = static_cast<std::uint64_t>(st.st_size);
  const std::uint64_t avail = size > h.data_offset ? size - h.data_offset : 0;
  const std::uint64_t pb = h.point_bytes();
  if (h.data == io::PcdData::kBinary && pb > 0 && h.points > avail / pb) {
    const bool wraps = h.points > UINT64_MAX / pb;
    throw InputError(path + ": truncated: the header claims " + std::to_string(h.points) + " points (" +
                     (wraps ? std::string("over 2^64") : std::to_string(h.points * pb)) + " bytes) but the file holds " +
                     std::to_string(avail) + " bytes of data (" + std::to_string(avail / pb) + " whole points)");
  }
}

Pass pass_from_table(io::PcdTable&& table, const std::string& source, std::size_t index) {
  const io::PcdHeader& h = table.header;
  const auto fail = [&](const std::string& msg) -> void { throw InputError(source + ": " + msg); };
  int idx[7];
  required_fields(h, source, idx);

  const std::size_t n = h.points;
  Pass p;
  p.index = index;
  p.source = source;
  p.organized = h.height > 1;
  auto col = [&](int r) -> std::vector<std::uint8_t>& { return table.columns[static_cast<std::size_t>(idx[r])]; };
  p.line = column_as<std::uint32_t>(col(0), n);
  p.beam = column_as<std::uint32_t>(col(1), n);
  p.range = column_as<float>(col(2), n);
  p.bearing = column_as<float>(col(3), n);
  p.amplitude = column_as<float>(col(4), n);
  p.nod = column_as<float>(col(5), n);
  p.stamp = column_as<double>(col(6), n);
  for (std::size_t i = 0; i < h.fields.size(); ++i) {
    if (std::find(std::begin(idx), std::end(idx), static_cast<int>(i)) != std::end(idx)) continue;
    if (h.fields[i].name == "_") continue;  // padding
    p.extra.push_back({h.fields[i], std::move(table.columns[i])});
  }

  // Order by (line, beam); unorganized files are accepted in any order (docs/data_contract.md).
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  const auto less = [&](std::size_t a, std::size_t b) {
    return p.line[a] != p.line[b] ? p.line[a] < p.line[b] : p.beam[a] < p.beam[b];
  };
  if (!std::is_sorted(order.begin(), order.end(), less)) {
    std::stable_sort(order.begin(), order.end(), less);
    permute(p.line, order);
    permute(p.beam, order);
    permute(p.range, order);
    permute(p.bearing, order);
    permute(p.amplitude, order);
    permute(p.nod, order);
    permute(p.stamp, order);
    for (auto& e : p.extra) {
      const std::size_t b = e.field.bytes();
      std::vector<std::uint8_t> out(e.data.size());
      for (std::size_t i = 0; i < n; ++i) std::memcpy(out.data() + i * b, e.data.data() + order[i] * b, b);
      e.data.swap(out);
    }
  }

  constexpr double kTwoPi = 6.283185307179586;
  const auto at = [&](std::size_t i) {
    return "line " + std::to_string(p.line[i]) + " beam " + std::to_string(p.beam[i]);
  };
  double prev_line_end = -INFINITY;
  std::size_t prev_line_first = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const bool new_line = i == 0 || p.line[i] != p.line[i - 1];
    if (!new_line && p.beam[i] == p.beam[i - 1]) fail(at(i) + ": appears twice (each (line, beam) must be unique)");
    const float r = p.range[i];
    if (std::isinf(r) || r < 0.0f)
      fail("field 'range', " + at(i) + ": " + std::to_string(r) +
           " is not a valid range (finite and >= 0; 0 or NaN means no return)");
    if (!std::isfinite(p.bearing[i]) || std::fabs(p.bearing[i]) > kTwoPi)
      fail("field 'bearing', " + at(i) + ": " + std::to_string(p.bearing[i]) + " is not a valid angle (finite, |bearing| <= 2 pi rad)");
    if (!std::isfinite(p.nod[i]) || std::fabs(p.nod[i]) > kTwoPi / 2)
      fail("field 'nod', " + at(i) + ": " + std::to_string(p.nod[i]) + " is not a valid angle (finite, |nod| <= pi rad)");
    if (!std::isfinite(p.stamp[i])) fail("field 'stamp', " + at(i) + ": stamp is not finite");
    const bool has_return = r > 0.0f && !std::isnan(r);
    // NaN amplitude: not measured (sensors and importers without intensity); the filters skip
    // their amplitude tests for it.
    if (has_return && !std::isnan(p.amplitude[i]) && (!std::isfinite(p.amplitude[i]) || p.amplitude[i] < 0.0f))
      fail("field 'amplitude', " + at(i) + ": " + std::to_string(p.amplitude[i]) +
           " is not a valid amplitude for a return (finite and >= 0, or NaN: not measured)");
    if (new_line) {
      if (i > 0) {
        // Close the previous line: its encoder time is its last stamp.
        prev_line_end = p.stamp[i - 1];
      }
      p.line_begin.push_back(i);
      prev_line_first = i;
      if (p.stamp[i] < prev_line_end && i > 0)
        fail("field 'stamp', " + at(i) + ": stamps must increase with time from line to line (" +
             std::to_string(p.stamp[i]) + " s is before the end of line " + std::to_string(p.line[i - 1]) + " at " +
             std::to_string(prev_line_end) + " s)");
    } else {
      if (p.nod[i] != p.nod[prev_line_first])
        fail("field 'nod', " + at(i) + ": differs within the line (" + std::to_string(p.nod[i]) + " vs " +
             std::to_string(p.nod[prev_line_first]) + " rad); the encoder is read once per line");
      if (p.stamp[i] < p.stamp[i - 1])
        fail("field 'stamp', " + at(i) + ": stamps must not decrease along a line (" + std::to_string(p.stamp[i]) +
             " s after " + std::to_string(p.stamp[i - 1]) + " s)");
    }
  }
  p.line_begin.push_back(n);
  // A line's reading is taken at its last return: consecutive lines must end at increasing times.
  for (std::size_t k = 1; k < p.line_count(); ++k) {
    const double a = p.stamp[p.line_begin[k] - 1], b = p.stamp[p.line_begin[k + 1] - 1];
    if (!(b > a))
      fail("field 'stamp', line " + std::to_string(p.line[p.line_begin[k]]) + ": ends at " + std::to_string(b) +
           " s, not after line " + std::to_string(p.line[p.line_begin[k] - 1]) + " (" + std::to_string(a) +
           " s); stamps must be strictly increasing from line to line");
  }

  p.label.assign(n, Label::kKept);
  p.flags.assign(n, 0);
  return p;
}

Pass read_pass(const std::string& path, std::size_t index) {
  try {
    return pass_from_table(io::read_pcd(path), path, index);
  } catch (const std::bad_alloc&) {  // an input too large for this machine is a data problem, not a bug
    throw InputError(path + ": out of memory while reading this pass (free memory, or split the pass)");
  }
}

}  // namespace pcdp
