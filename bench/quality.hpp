// Scoring shared by the quality benchmarks: precision, recall and F1 of a rejection mask against
// one truth label, with truth-valid returns as the false positives (rejecting other bad returns
// counts neither way).
#pragma once

#include <cstdio>
#include <string>
#include <vector>

#include "pcdp/core/labels.hpp"

namespace pcdp::bench {

struct Score {
  std::string method, params;
  double precision = 0, recall = 0, f1 = 0, valid_rejected = 0;
  std::uint64_t tp = 0, fp = 0, positives = 0, valid = 0;
};

inline Score score(const std::vector<Label>& truth, const std::vector<char>& rejected, Label positive, std::string method,
                   std::string params) {
  Score s{std::move(method), std::move(params)};
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const bool pos = truth[i] == positive, valid = truth[i] == Label::kKept;
    s.positives += pos;
    s.valid += valid;
    if (!rejected[i]) continue;
    s.tp += pos;
    s.fp += valid;
  }
  s.precision = s.tp + s.fp ? static_cast<double>(s.tp) / static_cast<double>(s.tp + s.fp) : 0.0;
  s.recall = s.positives ? static_cast<double>(s.tp) / static_cast<double>(s.positives) : 0.0;
  s.f1 = s.precision + s.recall > 0 ? 2 * s.precision * s.recall / (s.precision + s.recall) : 0.0;
  s.valid_rejected = s.valid ? static_cast<double>(s.fp) / static_cast<double>(s.valid) : 0.0;
  return s;
}

inline void print_header() {
  std::printf("  %-32s %-30s %9s %7s %7s %14s\n", "method", "best setting", "precision", "recall", "F1", "valid rejected");
}

inline void print(const Score& s) {
  std::printf("  %-32s %-30s %9.3f %7.3f %7.3f %12.3f %%  (%llu/%llu)\n", s.method.c_str(), s.params.c_str(), s.precision,
              s.recall, s.f1, 100.0 * s.valid_rejected, static_cast<unsigned long long>(s.tp),
              static_cast<unsigned long long>(s.positives));
}

}  // namespace pcdp::bench
