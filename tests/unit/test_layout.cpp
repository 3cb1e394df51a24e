// Keeps the layout of docs/architecture.md honest: the library's folders, what core/ and models/
// may include, the size of library sources, and the paths the docs name. Reads the source tree
// at PCDP_SOURCE_DIR.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "pcdp_test_paths.hpp"

namespace fs = std::filesystem;

namespace {

const fs::path kRoot = PCDP_SOURCE_DIR;

std::string read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

bool is_source(const fs::path& p) { return p.extension() == ".cpp" || p.extension() == ".hpp"; }

/// Every .cpp/.hpp under `dir` (recursively), as paths relative to the source root.
std::vector<std::string> sources_under(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(kRoot / dir))
    if (e.is_regular_file() && is_source(e.path())) out.push_back(fs::relative(e.path(), kRoot).generic_string());
  std::sort(out.begin(), out.end());
  return out;
}

/// The library sources allowed over the limit, each with the reason its size is earned.
const std::map<std::string, std::string> kLongSources = {
    {"lib/src/pipeline/config.cpp",
     "reads the pipeline YAML with one error message per rule it checks (file, line, key, rule); "
     "the option declarations move out of it as options are declared once (issue 35, item 3)"},
};
constexpr std::size_t kMaxLines = 650;

}  // namespace

TEST(Layout, NoSourceAtTheRoot) {
  for (const char* dir : {"lib/src", "lib/include/pcdp"}) {
    ASSERT_TRUE(fs::is_directory(kRoot / dir)) << dir;
    for (const auto& e : fs::directory_iterator(kRoot / dir))
      EXPECT_FALSE(e.is_regular_file() && is_source(e.path()))
          << fs::relative(e.path(), kRoot).generic_string()
          << ": a library source at the root; put it in the folder of its step (docs/architecture.md)";
  }
}

TEST(Layout, CoreAndModelsIncludeNoIoPipelineOrImport) {
  // Public headers are included as "pcdp/<folder>/x.hpp", internal ones as "<folder>/x.hpp".
  const std::vector<std::string> banned = {"pcdp/io/", "pcdp/pipeline/", "pcdp/import/",
                                           "\"io/",    "\"pipeline/",    "\"import/"};
  std::size_t files = 0;
  for (const char* dir : {"lib/include/pcdp/core", "lib/include/pcdp/models", "lib/src/core", "lib/src/models"}) {
    for (const std::string& f : sources_under(dir)) {
      ++files;
      std::istringstream in(read_all(kRoot / f));
      std::size_t n = 0;
      for (std::string line; std::getline(in, line);) {
        ++n;
        if (line.rfind("#include", 0) != 0) continue;
        for (const std::string& b : banned)
          EXPECT_EQ(line.find(b), std::string::npos)
              << f << ":" << n << ": " << line << ": core/ and models/ include no io, pipeline or import (docs/architecture.md)";
      }
    }
  }
  EXPECT_GT(files, 10u);  // the folders were found
}

TEST(Layout, NoLibrarySourceOverItsLimit) {
  std::size_t files = 0;
  for (const std::string& f : sources_under("lib")) {
    ++files;
    const std::string text = read_all(kRoot / f);
    const auto lines = static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n'));
    if (kLongSources.count(f)) continue;
    EXPECT_LE(lines, kMaxLines) << f << " has " << lines << " lines: split it by moving whole functions, or add it to "
                                << "kLongSources in tests/unit/test_layout.cpp with the reason its size is earned";
  }
  EXPECT_GT(files, 50u);
  // The allow-list names files that exist.
  for (const auto& [f, why] : kLongSources) EXPECT_TRUE(fs::exists(kRoot / f)) << f << " (" << why << ") no longer exists";
}

TEST(Layout, DocsNameOnlyPathsThatExist) {
  const auto path_char = [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == '/' || c == '-';
  };
  std::size_t named = 0;
  for (const auto& e : fs::directory_iterator(kRoot / "docs")) {
    if (e.path().extension() != ".md") continue;
    const std::string doc = "docs/" + e.path().filename().string();
    std::istringstream in(read_all(e.path()));
    std::size_t n = 0;
    for (std::string line; std::getline(in, line);) {
      ++n;
      for (const char* prefix : {"lib/", "tests/", "docs/"}) {
        for (std::size_t at = line.find(prefix); at != std::string::npos; at = line.find(prefix, at + 1)) {
          if (at > 0 && path_char(line[at - 1])) continue;  // inside a longer path or word
          std::size_t end = at;
          while (end < line.size() && path_char(line[end])) ++end;
          // A pattern, not a path: lib/src/<folder>/, stages/reject_*, tests/fuzz/crash-*, ...
          if (end < line.size() && (line[end] == '<' || line[end] == '*' || line[end] == '{' || line[end] == '$')) continue;
          std::string p = line.substr(at, end - at);
          while (!p.empty() && (p.back() == '.' || p.back() == ',')) p.pop_back();
          if (p.find("...") != std::string::npos) continue;
          ++named;
          EXPECT_TRUE(fs::exists(kRoot / p)) << doc << ":" << n << " names " << p << ", which does not exist";
        }
      }
    }
  }
  EXPECT_GT(named, 20u);
}
