// Binary reading and writing of partials (Partial::save / load, docs/scaling.md): little helpers
// that make a short or foreign stream an InputError. The caller adds the file's name.
#pragma once

#include <cstdint>
#include <istream>
#include <ostream>
#include <string>
#include <type_traits>
#include <vector>

#include "pcdp/core/errors.hpp"

namespace pcdp::partial_io {

template <class T>
void put(std::ostream& o, const T& v) {
  static_assert(std::is_trivially_copyable_v<T>);
  o.write(reinterpret_cast<const char*>(&v), sizeof v);
}
template <class T>
void get(std::istream& i, T& v) {
  static_assert(std::is_trivially_copyable_v<T>);
  if (!i.read(reinterpret_cast<char*>(&v), sizeof v)) throw InputError("the partial is truncated");
}
template <class T>
T get(std::istream& i) {
  T v{};
  get(i, v);
  return v;
}
template <class T>
void put_vec(std::ostream& o, const std::vector<T>& v) {
  static_assert(std::is_trivially_copyable_v<T>);
  put<std::uint64_t>(o, v.size());
  if (!v.empty()) o.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(T)));
}
/// At most `limit` elements (a foreign file must not allocate without bound).
template <class T>
void get_vec(std::istream& i, std::vector<T>& v, std::uint64_t limit = std::uint64_t{1} << 34) {
  const auto n = get<std::uint64_t>(i);
  if (n > limit / sizeof(T)) throw InputError("the partial is corrupt (a list of " + std::to_string(n) + " items)");
  v.resize(n);
  if (n && !i.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(n * sizeof(T))))
    throw InputError("the partial is truncated");
}
inline void put_str(std::ostream& o, const std::string& s) {
  put<std::uint64_t>(o, s.size());
  o.write(s.data(), static_cast<std::streamsize>(s.size()));
}
inline std::string get_str(std::istream& i) {
  const auto n = get<std::uint64_t>(i);
  if (n > (1u << 24)) throw InputError("the partial is corrupt (a string of " + std::to_string(n) + " bytes)");
  std::string s(n, '\0');
  if (n && !i.read(s.data(), static_cast<std::streamsize>(n))) throw InputError("the partial is truncated");
  return s;
}
/// A tag naming what follows; a different one is a foreign file.
inline void expect(std::istream& i, const std::string& tag) {
  const std::string got = get_str(i);
  if (got != tag) throw InputError("not a partial of this kind (expected '" + tag + "', found '" + got.substr(0, 40) + "')");
}

}  // namespace pcdp::partial_io
