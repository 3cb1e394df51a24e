// The SQLite storage of a ROS 2 bag (internal to import/rosbag2.cpp): its .db3 files, opened
// read-only, their topics and messages in time order. The message decoding (CDR) is io/cdr.hpp;
// what the messages mean (scans, joint states, odometry, TF) is import/rosbag2.cpp.
#pragma once

#include <sqlite3.h>

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "pcdp/core/errors.hpp"
#include "pcdp/import/rosbag2.hpp"

namespace pcdp::io::bag {

/// What a bag's tables must be, for error messages.
extern const char* const kTables;

/// The bag's .db3 files, in recording order: the files metadata.yaml lists, else the folder's
/// .db3 files by name, or the one .db3 file given. Throws InputError.
std::vector<std::string> bag_files(const std::string& path);

/// One .db3 file, opened read-only (immutable: no lock, no journal written beside it).
class Db {
 public:
  explicit Db(std::string path);
  ~Db() { sqlite3_close(db_); }
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;

  const std::string& path() const { return path_; }

  /// A prepared statement; a missing table or column is the bag's fault.
  std::unique_ptr<sqlite3_stmt, int (*)(sqlite3_stmt*)> prepare(const char* sql) {
    sqlite3_stmt* st = nullptr;
    if (sqlite3_prepare_v2(db_, sql, -1, &st, nullptr) != SQLITE_OK) {
      const std::string msg = sqlite3_errmsg(db_);
      sqlite3_finalize(st);
      throw InputError(path_ + ": " + msg + ": " + kTables);
    }
    return {st, sqlite3_finalize};
  }
  /// sqlite3_step, SQLITE_ROW -> true, SQLITE_DONE -> false, anything else: the file is damaged.
  bool step(sqlite3_stmt* st, const std::string& what) {
    const int rc = sqlite3_step(st);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throw InputError(path_ + ": reading " + what + ": " + sqlite3_errmsg(db_) + " (a damaged or truncated .db3?)");
  }

 private:
  std::string path_;
  sqlite3* db_ = nullptr;
};

struct Topic {
  std::string name, type, format;
};

std::string text_column(sqlite3_stmt* st, int col);

/// The topics of one file, by id.
std::map<long long, Topic> read_topics(Db& db);

/// Where a message is, for error messages: "bag.db3: topic /scan, message 17 (id 123, bag time 1748... ns)".
struct MsgRef {
  const std::string* file;
  const std::string* topic;
  std::size_t index;  ///< on its topic, over the whole bag, from 0
  long long id, t_ns;
  std::string where() const {
    return *file + ": topic " + *topic + ", message " + std::to_string(index) + " (id " + std::to_string(id) +
           ", bag time " + std::to_string(t_ns) + " ns)";
  }
};

/// Calls fn(ref, data, size) for every message of `topic` in `db`, in time order; counts on.
template <typename Fn>
void for_each_message(Db& db, const std::map<long long, Topic>& topics, const std::string& topic, std::size_t& index,
                      Fn&& fn) {
  long long topic_id = -1;
  bool found = false;
  for (const auto& [id, t] : topics)
    if (t.name == topic) topic_id = id, found = true;
  if (!found) return;
  auto st = db.prepare("SELECT id, timestamp, data FROM messages WHERE topic_id = ? ORDER BY timestamp, id");
  sqlite3_bind_int64(st.get(), 1, topic_id);
  while (db.step(st.get(), "the messages of " + topic)) {
    MsgRef ref{&db.path(), &topic, index++, sqlite3_column_int64(st.get(), 0), sqlite3_column_int64(st.get(), 1)};
    if (sqlite3_column_type(st.get(), 1) != SQLITE_INTEGER)
      throw InputError(ref.where() + ": the timestamp is not an integer (ns)");
    if (ref.t_ns < 0 || ref.t_ns > kMaxBagTimeNs)
      throw InputError(ref.where() + ": the timestamp is outside 0 .. 4e18 ns");
    const int type = sqlite3_column_type(st.get(), 2);
    if (type != SQLITE_BLOB && type != SQLITE_NULL) throw InputError(ref.where() + ": the data is not a blob");
    const void* blob = sqlite3_column_blob(st.get(), 2);
    const int n = sqlite3_column_bytes(st.get(), 2);
    try {
      fn(ref, static_cast<const std::uint8_t*>(blob), static_cast<std::size_t>(n));
    } catch (const InputError& e) {
      const std::string what = e.what();
      // The decoders report "byte N: rule"; say where.
      if (what.rfind("byte ", 0) == 0) throw InputError(ref.where() + ": " + what);
      throw;
    }
  }
}

}  // namespace pcdp::io::bag
