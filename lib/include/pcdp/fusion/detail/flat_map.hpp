// A small open-addressing hash map from 63-bit keys to values, for the hot voxel maps
// (check_consistency): one probe sequence in two flat arrays, no node allocation. Keys must not be
// ~0 (the empty marker). Iteration order is the slot order: do not depend on it.
//
// `salt` decorrelates tables: iterating one table visits its keys in hash order, and inserting them
// in that order into another table with the same hash piles them into long probe runs (a pass's
// cells into the run's map took 13x longer). Give tables that feed each other different salts.
//
// detail/: implementation that public fusion headers include for their members; not API, may
// change without notice (docs/architecture.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace pcdp {

template <class V>
class FlatMap {
 public:
  static constexpr std::uint64_t kEmpty = ~0ull;

  explicit FlatMap(std::uint64_t salt = 0) : mult_(multiplier(salt)) { rehash(16); }
  std::size_t size() const { return size_; }

  /// The value of `key`, inserted default-constructed if absent.
  V& operator[](std::uint64_t key) {
    if (2 * (size_ + 1) > keys_.size()) rehash(2 * keys_.size());  // load factor at most 1/2
    std::size_t i = slot(key);
    while (keys_[i] != key) {
      if (keys_[i] == kEmpty) {
        keys_[i] = key;
        ++size_;
        break;
      }
      i = (i + 1) & mask_;
      ++probes_;
    }
    return vals_[i];
  }

  /// nullptr when absent.
  const V* find(std::uint64_t key) const {
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (keys_[i] == key) return &vals_[i];
      if (keys_[i] == kEmpty) return nullptr;
    }
  }

  void reserve(std::size_t n) {
    std::size_t cap = keys_.size();
    while (cap < 2 * n) cap *= 2;
    if (cap != keys_.size()) rehash(cap);
  }

  template <class F>
  void for_each(F&& f) const {
    for (std::size_t i = 0; i < keys_.size(); ++i)
      if (keys_[i] != kEmpty) f(keys_[i], vals_[i]);
  }

  /// Slots stepped over by operator[] so far, beyond the first one tried (a diagnostic).
  std::uint64_t probes() const { return probes_; }

 private:
  // Multiplicative hashing, top bits; the salt picks another odd multiplier (a full mixer such as
  // splitmix64's finaliser measured 15 % slower on the voxel walks).
  std::size_t slot(std::uint64_t key) const { return static_cast<std::size_t>((key * mult_) >> shift_); }
  /// Salt 0: the golden-ratio multiplier; any other salt: an odd multiplier drawn from it by
  /// splitmix64 (so that near salts still give unrelated multipliers).
  static std::uint64_t multiplier(std::uint64_t salt) {
    if (salt == 0) return 0x9E3779B97F4A7C15ull;
    std::uint64_t h = salt + 0x9E3779B97F4A7C15ull;
    h = (h ^ (h >> 30)) * 0xBF58476D1CE4E5B9ull;
    h = (h ^ (h >> 27)) * 0x94D049BB133111EBull;
    return (h ^ (h >> 31)) | 1;
  }

  void rehash(std::size_t cap) {  // cap: a power of two
    std::vector<std::uint64_t> old_keys(cap, kEmpty);
    std::vector<V> old_vals(cap);
    old_keys.swap(keys_);
    old_vals.swap(vals_);
    mask_ = cap - 1;
    shift_ = 64;
    for (std::size_t c = cap; c > 1; c >>= 1) --shift_;
    size_ = 0;
    for (std::size_t i = 0; i < old_keys.size(); ++i)
      if (old_keys[i] != kEmpty) (*this)[old_keys[i]] = old_vals[i];
  }

  std::vector<std::uint64_t> keys_;
  std::vector<V> vals_;
  std::uint64_t mult_;
  std::uint64_t probes_ = 0;
  std::size_t size_ = 0, mask_ = 0;
  unsigned shift_ = 64;
};

}  // namespace pcdp
