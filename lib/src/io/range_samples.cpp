#include "pcdp/io/range_samples.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

#include "pcdp/core/errors.hpp"
#include "pcdp/io/input_file.hpp"

namespace pcdp::io {

void read_range_samples_csv(const std::string& path, std::vector<double>& y, std::vector<double>& z) {
  io::require_regular_file(path, "range sample file");
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open (" + std::strerror(errno) + ")");
  std::string line;
  if (!std::getline(in, line)) throw InputError(path + ": empty file (expected a header with columns true,measured)");
  std::vector<std::string> cols;
  {
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) {
      c.erase(std::remove_if(c.begin(), c.end(), [](char ch) { return ch == ' ' || ch == '\r'; }), c.end());
      cols.push_back(c);
    }
  }
  const auto ti = std::find(cols.begin(), cols.end(), "true"), mi = std::find(cols.begin(), cols.end(), "measured");
  if (ti == cols.end() || mi == cols.end())
    throw InputError(path + ":1: the header must name the columns 'true' and 'measured' (m), got '" + line + "'");
  const std::size_t tcol = static_cast<std::size_t>(ti - cols.begin()), mcol = static_cast<std::size_t>(mi - cols.begin());
  std::size_t lineno = 1;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
    if (cells.size() != cols.size())
      throw InputError(path + ":" + std::to_string(lineno) + ": has " + std::to_string(cells.size()) + " columns, the header " +
                       std::to_string(cols.size()));
    double v[2];
    const std::size_t idx[2] = {tcol, mcol};
    for (int k = 0; k < 2; ++k) {
      char* end = nullptr;
      v[k] = std::strtod(cells[idx[k]].c_str(), &end);
      // Trailing blanks (and a CRLF line end) only: "1.5 junk" is not a number.
      if (cells[idx[k]].empty() || end == cells[idx[k]].c_str() ||
          std::string(end).find_first_not_of(" \t\r") != std::string::npos || !std::isfinite(v[k]))
        throw InputError(path + ":" + std::to_string(lineno) + ": column '" + (k ? "measured" : "true") + "': '" +
                         cells[idx[k]] + "' is not a finite number");
      if (!(v[k] > 0))
        throw InputError(path + ":" + std::to_string(lineno) + ": column '" + (k ? "measured" : "true") + "': " +
                         cells[idx[k]] + " is not a range (ranges are positive distances in metres)");
    }
    y.push_back(v[0]);
    z.push_back(v[1]);
  }
}

}  // namespace pcdp::io
