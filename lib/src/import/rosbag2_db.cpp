#include "import/rosbag2_db.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "pcdp/io/input_file.hpp"

namespace pcdp::io::bag {

namespace fs = std::filesystem;

const char* const kTables =
    "a ROS 2 sqlite3 bag has the tables topics(id, name, type, serialization_format) and "
    "messages(id, topic_id, timestamp, data)";

namespace {
std::string uri_escape(const std::string& path) {
  std::string out;
  for (unsigned char c : path) {
    if (std::isalnum(c) || c == '/' || c == '.' || c == '_' || c == '-') {
      out += static_cast<char>(c);
    } else {
      char buf[4];
      std::snprintf(buf, sizeof buf, "%%%02X", c);
      out += buf;
    }
  }
  return out;
}
}  // namespace

/// The bag's .db3 files, in recording order.
std::vector<std::string> bag_files(const std::string& path) {
  std::error_code ec;
  if (!fs::is_directory(path, ec)) {
    const std::string why = regular_file_problem(path, "ROS 2 bag (a folder with metadata.yaml, or a .db3 file)");
    if (!why.empty()) throw InputError(path + ": " + why);
    return {path};
  }
  const fs::path meta = fs::path(path) / "metadata.yaml";
  std::vector<std::string> files;
  if (fs::exists(meta, ec)) {
    require_regular_file(meta.string(), "bag metadata file");
    YAML::Node root;
    try {
      root = YAML::LoadFile(meta.string());
    } catch (const YAML::Exception& e) {
      throw InputError(meta.string() + ":" + std::to_string(e.mark.line + 1) + ": not valid YAML (" + e.msg + ")");
    }
    const auto field = [&](const YAML::Node& n, const char* key) -> std::string {
      try {
        return n[key] && n[key].IsScalar() ? n[key].as<std::string>() : std::string();
      } catch (const YAML::Exception&) {
        return {};
      }
    };
    const YAML::Node info = root.IsMap() ? root["rosbag2_bagfile_information"] : YAML::Node();
    if (!info || !info.IsMap())
      throw InputError(meta.string() + ": no map rosbag2_bagfile_information (is this a ROS 2 bag's metadata.yaml?)");
    const std::string storage = field(info, "storage_identifier");
    if (storage != "sqlite3")
      throw InputError(meta.string() + ": storage_identifier '" + storage + "': only sqlite3 storage (.db3) is read" +
                       (storage == "mcap" ? " (convert with `ros2 bag convert` to storage sqlite3)" : ""));
    const std::string compression = field(info, "compression_format");
    if (!compression.empty())
      throw InputError(meta.string() + ": compression_format '" + compression +
                       "': compressed bags are not read (decompress with `ros2 bag convert`)");
    const YAML::Node rel = info["relative_file_paths"];
    if (!rel || !rel.IsSequence() || rel.size() == 0)
      throw InputError(meta.string() + ": relative_file_paths is missing or empty");
    for (const auto& f : rel) {
      if (!f.IsScalar()) throw InputError(meta.string() + ": relative_file_paths holds a non-string entry");
      const fs::path p = fs::path(path) / fs::path(f.as<std::string>()).filename();
      files.push_back(p.string());
    }
    return files;
  }
  for (const auto& e : fs::directory_iterator(path, ec))
    if (e.path().extension() == ".db3") files.push_back(e.path().string());
  if (ec) throw InputError(path + ": cannot list the folder (" + ec.message() + ")");
  std::sort(files.begin(), files.end());
  if (files.empty()) throw InputError(path + ": no metadata.yaml and no .db3 file: not a ROS 2 bag (sqlite3 storage)");
  return files;
}

Db::Db(std::string path) : path_(std::move(path)) {
  require_regular_file(path_, "ROS 2 bag file (.db3, SQLite)");
  {
    std::ifstream in(path_, std::ios::binary);
    char magic[16] = {};
    in.read(magic, 16);
    if (in.gcount() != 16 || std::memcmp(magic, "SQLite format 3\0", 16) != 0)
      throw InputError(path_ + ": byte 0: not an SQLite database (no \"SQLite format 3\" header); " + kTables);
  }
  const std::string uri = "file:" + uri_escape(path_) + "?immutable=1";
  if (sqlite3_open_v2(uri.c_str(), &db_, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr) != SQLITE_OK) {
    const std::string msg = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    db_ = nullptr;
    throw InputError(path_ + ": cannot open as SQLite (" + msg + ")");
  }
}

std::string text_column(sqlite3_stmt* st, int col) {
  const unsigned char* s = sqlite3_column_text(st, col);
  return s ? std::string(reinterpret_cast<const char*>(s), static_cast<std::size_t>(sqlite3_column_bytes(st, col)))
           : std::string();
}

/// The topics of one file, by id.
std::map<long long, Topic> read_topics(Db& db) {
  auto st = db.prepare("SELECT id, name, type, serialization_format FROM topics");
  std::map<long long, Topic> out;
  while (db.step(st.get(), "table topics")) {
    if (sqlite3_column_type(st.get(), 0) != SQLITE_INTEGER)
      throw InputError(db.path() + ": table topics: an id is not an integer");
    const long long id = sqlite3_column_int64(st.get(), 0);
    Topic t{text_column(st.get(), 1), text_column(st.get(), 2), text_column(st.get(), 3)};
    if (t.name.empty() || t.type.empty())
      throw InputError(db.path() + ": table topics: topic id " + std::to_string(id) + " has no name or type");
    if (!out.emplace(id, t).second)
      throw InputError(db.path() + ": table topics: id " + std::to_string(id) + " appears twice");
  }
  return out;
}

}  // namespace pcdp::io::bag
