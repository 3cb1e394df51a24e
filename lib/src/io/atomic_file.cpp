#include "pcdp/io/atomic_file.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <set>

#include "io/signal_cleanup.hpp"
#include "pcdp/core/errors.hpp"
#include "pcdp/io/paths.hpp"

namespace fs = std::filesystem;

namespace pcdp::io {

namespace {

std::string errno_text(int e) { return std::strerror(e); }

using cleanup::BlockSignals;
using cleanup::register_temp;
using cleanup::SwapGuard;
using cleanup::unregister_temp;

// ---- the test hook -----------------------------------------------------------------------------

detail::CommitStepHook g_hook = nullptr;

int env_hook(int step, const char*) {
  static const char* spec = std::getenv("PCDP_TEST_COMMIT_FAULT");
  if (!spec) return 0;
  const std::string s = spec;
  const auto colon = s.find(':');
  if (colon == std::string::npos || std::atoi(s.c_str() + colon + 1) != step) return 0;
  if (s.compare(0, colon, "kill") == 0) ::kill(::getpid(), SIGKILL);
  return s.compare(0, colon, "fail") == 0 ? EIO : 0;
}

/// One filesystem step of a commit: the hook may fail it (returns errno) or kill the process.
class Steps {
 public:
  int next(const char* what) {
    ++n_;
    return g_hook ? g_hook(n_, what) : env_hook(n_, what);
  }

 private:
  int n_ = 0;
};

int do_rename(Steps& st, const char* what, const std::string& a, const std::string& b) {
  if (const int e = st.next(what)) return e;
  return std::rename(a.c_str(), b.c_str()) == 0 ? 0 : errno;
}

#ifndef RENAME_EXCHANGE
#define RENAME_EXCHANGE (1 << 1)
#endif
int do_exchange(Steps& st, const char* what, const std::string& a, const std::string& b) {
  if (const int e = st.next(what)) return e;
  return ::syscall(SYS_renameat2, AT_FDCWD, a.c_str(), AT_FDCWD, b.c_str(), RENAME_EXCHANGE) == 0 ? 0 : errno;
}
bool exchange_unsupported(int e) { return e == EINVAL || e == ENOSYS || e == EOPNOTSUPP || e == ENOTSUP; }

std::string pid_text() { return std::to_string(::getpid()); }

/// True when `p` is the root of a mount (another filesystem, a bind mount or a btrfs subvolume
/// root): it cannot be renamed, and its contents belong to that mount.
bool is_mount_root(const fs::path& p) {
  struct statx sx {};
  if (::statx(AT_FDCWD, p.c_str(), AT_SYMLINK_NOFOLLOW, STATX_BASIC_STATS, &sx) == 0 &&
      (sx.stx_attributes_mask & STATX_ATTR_MOUNT_ROOT))
    return (sx.stx_attributes & STATX_ATTR_MOUNT_ROOT) != 0;
  struct stat me {}, up {};  // kernels before 5.8: a change of device
  return ::lstat(p.c_str(), &me) == 0 && ::stat(p.parent_path().c_str(), &up) == 0 && me.st_dev != up.st_dev;
}

/// Removes a leftover of this tool (a staging folder or an old set), making its folders writable
/// first where a copied mode made them read-only; best effort.
void remove_tree(const fs::path& p) {
  std::error_code ec;
  fs::remove_all(p, ec);
  if (!ec) return;
  struct stat s {};
  if (::lstat(p.c_str(), &s) != 0 || !S_ISDIR(s.st_mode)) return;
  ::chmod(p.c_str(), (s.st_mode & 07777) | S_IRWXU);
  for (fs::recursive_directory_iterator it(p, ec), end; !ec && it != end; it.increment(ec))
    if (::lstat(it->path().c_str(), &s) == 0 && S_ISDIR(s.st_mode)) ::chmod(it->path().c_str(), (s.st_mode & 07777) | S_IRWXU);
  fs::remove_all(p, ec);
}

/// `<parent>/.<name>.pcdp-<what>`
std::string beside(const fs::path& target, const std::string& what) {
  return (target.parent_path() / ("." + target.filename().string() + ".pcdp-" + what)).string();
}

/// Absolute, normal form, no trailing separator; the final component's symlinks resolved (the
/// folder itself is swapped, not a link to it).
fs::path output_target(const std::string& p) {
  fs::path t = fs::absolute(fs::path(p)).lexically_normal();
  if (t.filename().empty()) t = t.parent_path();
  std::error_code ec;
  if (fs::is_symlink(fs::symlink_status(t, ec))) {
    const fs::path c = fs::canonical(t, ec);
    if (ec) throw OutputError("'" + p + "' is a symbolic link to nothing (" + ec.message() + ")");
    t = c;
  }
  return t;
}

/// Carries `src` (an entry of the old folder) into the staging folder: hard links for files (a
/// copy where links are refused), the same tree for folders, the same target for symlinks.
int carry_over(Steps& st, const fs::path& src, const fs::path& dst, std::string& why) {
  std::error_code ec;
  const fs::file_status s = fs::symlink_status(src, ec);
  if (ec) {
    why = "cannot carry " + src.string() + " over to the new set";
    return ec.value();
  }
  if (const int e = st.next("carry over")) {
    why = "cannot carry " + src.string() + " over to the new set";
    return e;
  }
  if (fs::is_symlink(s)) {
    fs::copy_symlink(src, dst, ec);
  } else if (fs::is_directory(s)) {
    // A filesystem mounted inside the output folder is not copied (nor later deleted with the old set).
    if (is_mount_root(src)) {
      why = src.string() + " is a mount point: it cannot be carried over to the new set (unmount it or write elsewhere)";
      return EXDEV;
    }
    fs::create_directory(dst, src, ec);
    if (!ec)
      for (const auto& e : fs::directory_iterator(src, ec)) {
        if (const int r = carry_over(st, e.path(), dst / e.path().filename(), why)) return r;
      }
  } else if (fs::is_regular_file(s)) {
    if (::link(src.c_str(), dst.c_str()) != 0) {  // another filesystem below, no hard links, protected_hardlinks
      fs::copy_file(src, dst, ec);
      if (!ec) fs::permissions(dst, fs::status(src).permissions(), ec);
    }
  } else if (s.type() == fs::file_type::fifo) {
    if (::mkfifo(dst.c_str(), static_cast<mode_t>(s.permissions())) != 0) ec.assign(errno, std::generic_category());
  } else {
    why = src.string() + " is a socket or device: it cannot be carried over to the new set";
    return EINVAL;
  }
  if (ec) {
    why = "cannot carry " + src.string() + " over to the new set";
    return ec.value() ? ec.value() : EIO;
  }
  return 0;
}

/// Temporaries of earlier versions, which staged products inside the output folder as
/// `.<product>.tmp-<pid>` (plus `.body`, `.tmp-write.tif`, `.tmp-png`): a killed run left them
/// there. They are not carried over to a new set.
bool legacy_temporary(const std::string& n) {
  if (n.size() < 2 || n[0] != '.') return false;
  std::string base = n;
  for (const char* suffix : {".body", ".tmp-write.tif", ".tmp-png"}) {
    const std::string sfx = suffix;
    if (base.size() > sfx.size() && base.compare(base.size() - sfx.size(), sfx.size(), sfx) == 0) {
      base.resize(base.size() - sfx.size());
      break;
    }
  }
  const auto at = base.rfind(".tmp-");
  if (at == std::string::npos || at == 0 || at + 5 == base.size()) return false;
  // Only temporaries of a product name ('.notes.tmp-2024' is a user's file).
  static const std::set<std::string> kProducts = {"returns.pcd", "cloud.pcd",           "report.json", "elevation.tif",
                                                  "elevation.png", "elevation.state.tif", "map.bt",      "map.ot"};
  if (!kProducts.count(base.substr(1, at - 1))) return false;
  for (std::size_t i = at + 5; i < base.size(); ++i)
    if (base[i] < '0' || base[i] > '9') return false;
  return true;
}

bool has_control(const std::string& s) {
  for (unsigned char c : s)
    if (c < 0x20 || c == 0x7f) return true;
  return false;
}

}  // namespace
void detail::set_commit_step_hook(CommitStepHook hook) { g_hook = hook; }


void check_output_path(const std::string& key, const std::string& path) {
  if (path.empty()) throw ConfigError(key + ": the output path is empty");
  if (has_control(path))
    throw ConfigError(key + ": the output path contains a control character (a newline, tab, ...): refused");
  const fs::path t = fs::path(path).lexically_normal();
  const std::string name = (t.filename().empty() ? t.parent_path() : t).filename().string();
  if (name.empty() || name == "." || name == ".." || t == t.root_path())
    throw ConfigError(key + ": '" + path + "' names no folder that can be replaced; give a folder below the current one");
}

// ---- OutputLock ------------------------------------------------------------------------------

OutputLock::OutputLock(const std::string& target) : path_(beside(fs::path(target), "lock")) {
  const BlockSignals hold;  // the file is registered for the signal cleanup before a signal can act
  for (int attempt = 0; attempt < 100; ++attempt) {
    fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd_ < 0 && errno == ENAMETOOLONG)
      throw OutputError(target + ": the name '" + fs::path(target).filename().string() + "' (" +
                        std::to_string(fs::path(target).filename().string().size()) +
                        " bytes) is too long for the files beside it that a run needs (." +
                        "<name>.pcdp-lock and the staging folder add 12 to 16 bytes; a name holds at most 255): "
                        "choose a shorter one");
    if (fd_ < 0)
      throw OutputError(target + ": cannot create the lock file " + path_ + " (" + errno_text(errno) +
                        "); the folder that holds the output must be writable");
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      const int e = errno;
      char buf[32] = {};
      const ssize_t n = ::pread(fd_, buf, sizeof buf - 1, 0);
      ::close(fd_);
      fd_ = -1;
      if (e == EWOULDBLOCK)
        throw OutputError(target + ": another pcd_pipeline process" +
                          (n > 0 ? " (pid " + std::string(buf, static_cast<std::size_t>(n)) + ")" : std::string()) +
                          " is writing this output now (it holds " + path_ +
                          "); wait for it to finish or choose another output");
      throw OutputError(target + ": cannot lock " + path_ + " (" + errno_text(e) + ")");
    }
    // The holder before us removes the file as it releases it: lock the file that is there now.
    struct stat a {}, b {};
    if (::fstat(fd_, &a) == 0 && ::stat(path_.c_str(), &b) == 0 && a.st_ino == b.st_ino && a.st_dev == b.st_dev) {
      const std::string pid = pid_text();
      if (::ftruncate(fd_, 0) == 0 && ::pwrite(fd_, pid.data(), pid.size(), 0) < 0) {
      }
      slot_ = register_temp(path_, 1);
      return;
    }
    ::close(fd_);
    fd_ = -1;
  }
  throw OutputError(target + ": cannot take the lock " + path_ + " (it keeps being replaced)");
}

OutputLock::~OutputLock() {
  if (fd_ < 0) return;
  unregister_temp(slot_);
  ::unlink(path_.c_str());  // still holding it: a process waiting on the old file retries (above)
  ::close(fd_);
}

// ---- StagedOutputs ---------------------------------------------------------------------------

StagedOutputs::StagedOutputs(std::string dir) : dir_(std::move(dir)) {
  check_output_path("output_dir", dir_);
  const fs::path t = output_target(dir_);
  target_ = t.string();
  std::error_code ec;
  // Missing parents are created (and removed again if the run fails).
  std::vector<fs::path> missing;
  for (fs::path p = t.parent_path(); !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
    missing.push_back(p);
    if (p == p.parent_path()) break;
  }
  try {
    for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
      if (!fs::create_directory(*it, ec) && ec)
        throw OutputError("output_dir '" + dir_ + "': cannot create the folder " + it->string() + " (" + ec.message() + ")");
      created_parents_.push_back(it->string());
    }
    if (!fs::is_directory(t.parent_path(), ec))
      throw OutputError("output_dir '" + dir_ + "': " + t.parent_path().string() + " is not a folder");
    if (fs::is_directory(fs::symlink_status(t, ec)) && is_mount_root(t))
      throw OutputError("output_dir '" + dir_ + "' is a mount point (a volume, or a filesystem's root): outputs are "
                        "committed by swapping the folder with a complete new one beside it, which a mount point "
                        "cannot be; write into a folder inside it instead (e.g. --output-dir " +
                        (fs::path(dir_) / "run").string() + ")");
    lock_ = std::make_unique<OutputLock>(target_);
    const fs::file_status st = fs::symlink_status(t, ec);
    if (fs::exists(st) && !fs::is_directory(st))
      throw OutputError("output_dir '" + dir_ + "' exists and is not a folder");
    // A folder its owner made read-only is not to be replaced (the swap itself would only need
    // its parent to be writable, and would leave the old set, unremovable, beside it).
    if (fs::exists(st) && ::access(target_.c_str(), W_OK) != 0)
      throw OutputError("output_dir '" + dir_ + "' is read-only (" + errno_text(errno) +
                        "); make it writable or choose another folder");
    // Holding the lock, every .<name>.pcdp-* beside the folder is a leftover of a killed run. A
    // set renamed aside (no RENAME_EXCHANGE) whose folder is gone is the complete old set: back.
    const std::string prefix = "." + t.filename().string() + ".pcdp-";
    std::vector<fs::path> leftovers;
    for (const auto& e : fs::directory_iterator(t.parent_path(), ec)) {
      const std::string n = e.path().filename().string();
      if (n.rfind(prefix, 0) == 0 && n != prefix + "lock") leftovers.push_back(e.path());
    }
    for (const auto& l : leftovers) {
      const std::string n = l.filename().string();
      if (n.rfind(prefix + "old-", 0) == 0 && !fs::exists(fs::symlink_status(t, ec)) && std::rename(l.c_str(), t.c_str()) == 0)
        continue;
      remove_tree(l);
    }
    staging_ = beside(t, "new-" + pid_text());
    const BlockSignals hold;
    if (::mkdir(staging_.c_str(), 0777) != 0)
      throw OutputError("output_dir '" + dir_ + "': cannot create the staging folder " + staging_ + " (" +
                        errno_text(errno) + "); the folder that holds the output must be writable");
    slot_ = register_temp(staging_, 2);
  } catch (...) {
    lock_.reset();
    for (auto it = created_parents_.rbegin(); it != created_parents_.rend(); ++it) ::rmdir(it->c_str());
    throw;
  }
}

StagedOutputs::~StagedOutputs() {
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(staging_, ec);
  }
  unregister_temp(slot_);
  lock_.reset();
  if (!committed_)
    for (auto it = created_parents_.rbegin(); it != created_parents_.rend(); ++it) ::rmdir(it->c_str());
}

void StagedOutputs::check_replaceable(const std::vector<std::string>& filenames) const {
  std::error_code ec;
  for (const auto& f : filenames) {
    const fs::path p = fs::path(target_) / f;
    if (fs::is_directory(fs::symlink_status(p, ec)))
      throw OutputError(final_path(f) + ": a folder has the name of an output of this run; rename or remove it");
  }
}

void StagedOutputs::owns(std::vector<std::string> names) {
  owned_ = std::move(names);
  for (const auto& n : owned_) check_inputs(n);
}

namespace {
/// The inputs that lie inside `folder` (at any depth, symlinks resolved): (as given, the name of
/// the folder's entry that holds it).
std::vector<std::pair<std::string, std::string>> inputs_inside(const std::string& folder, const std::vector<std::string>& inputs) {
  std::vector<std::pair<std::string, std::string>> out;
  const fs::path f = resolved_path(folder);
  if (f.empty()) return out;
  for (const auto& in : inputs) {
    if (in.empty()) continue;
    const fs::path p = resolved_path(in);
    if (p.empty()) continue;
    const fs::path rel = p.lexically_relative(f);
    if (!rel.empty() && *rel.begin() != ".." && *rel.begin() != ".") out.emplace_back(in, rel.begin()->string());
  }
  return out;
}

[[noreturn]] void refuse_input(const std::string& given, const std::string& dir, const std::string& name) {
  throw ConfigError("input '" + given + "' is in the output folder '" + dir + "' as '" + name +
                    "', a name this command writes or replaces there: the commit would replace it; move the input or "
                    "choose another output folder");
}
}  // namespace

void check_inputs_not_replaced(const std::string& dir, const std::vector<std::string>& inputs,
                               const std::vector<std::string>& names) {
  for (const auto& [given, entry] : inputs_inside(dir, inputs))
    if (std::count(names.begin(), names.end(), entry)) refuse_input(given, dir, entry);
}

void StagedOutputs::protect_inputs(const std::vector<std::string>& inputs) {
  for (auto& i : inputs_inside(target_, inputs)) inputs_.push_back(std::move(i));
  for (const auto& n : owned_) check_inputs(n);
  for (const auto& n : names_) check_inputs(n);
}

void StagedOutputs::check_inputs(const std::string& name) const {
  for (const auto& [given, entry] : inputs_)
    if (entry == name) refuse_input(given, dir_, name);
}

std::string StagedOutputs::staged_path(const std::string& filename) {
  for (const auto& n : names_)
    if (n == filename) throw std::logic_error("two products named " + filename + " in one run");
  check_inputs(filename);
  names_.push_back(filename);
  return (fs::path(staging_) / filename).string();
}

std::string StagedOutputs::final_path(const std::string& filename) const {
  return (fs::path(dir_) / filename).string();
}

std::vector<std::string> StagedOutputs::final_paths() const {
  std::vector<std::string> out;
  for (const auto& n : names_) out.push_back(final_path(n));
  return out;
}

void StagedOutputs::commit() {
  // A folder that cannot be listed midway (std::filesystem throws from an iterator's increment) is
  // an output problem like any other step's failure, never an internal error.
  try {
    commit_steps();
  } catch (const fs::filesystem_error& e) {
    throw OutputError("output_dir '" + dir_ + "': " + e.what() +
                      (committed_ ? "; the new outputs are in place" : "; the folder keeps its earlier contents"));
  }
}

void StagedOutputs::commit_steps() {
  Steps st;
  std::error_code ec;
  const fs::path t(target_), stage(staging_);
  const auto fail = [&](const std::string& what, int e) {
    throw OutputError("output_dir '" + dir_ + "': " + what + " (" + errno_text(e) +
                      "); the folder keeps its earlier contents");
  };
  // The new set: whatever the staging folder holds (the products, and anything a command wrote
  // there directly, such as simulate's truth/ folder).
  std::set<std::string> products;
  for (const auto& e : fs::directory_iterator(stage, ec)) products.insert(e.path().filename().string());
  if (ec) fail("cannot list the staging folder " + staging_, ec.value());
  for (const auto& n : products) check_inputs(n);  // products a command wrote straight into the folder
  const bool had_old = fs::exists(fs::symlink_status(t, ec));
  if (had_old) {
    // A folder is replaced only by a folder (a user's folder named like a product stays).
    for (const auto& n : products)
      if (fs::is_directory(fs::symlink_status(t / n, ec)) && !fs::is_directory(fs::symlink_status(stage / n, ec)))
        throw OutputError(final_path(n) + ": a folder has the name of an output of this run; rename or remove it"
                          " (the folder keeps its earlier contents)");
    // The old folder's other entries join the new set (hard links: the same files).
    struct stat s {};
    if (::stat(target_.c_str(), &s) == 0) ::chmod(staging_.c_str(), s.st_mode & 07777);
    for (const auto& e : fs::directory_iterator(t, ec)) {
      const std::string n = e.path().filename().string();
      if (products.count(n) || legacy_temporary(n) || std::count(owned_.begin(), owned_.end(), n)) continue;
      std::string why;
      if (const int r = carry_over(st, e.path(), stage / n, why)) fail(why, r);
    }
    if (ec) fail("cannot list the folder", ec.value());
  }
  {
    SwapGuard guard;  // SIGINT/SIGTERM wait until the swap is done
    std::string old_set = staging_;  // where the old set is once swapped
    if (!had_old) {
      if (const int e = do_rename(st, "rename into place", staging_, target_)) fail("cannot rename " + staging_ + " into place", e);
    } else if (int e = do_exchange(st, "exchange", staging_, target_)) {
      if (!exchange_unsupported(e)) fail("cannot swap " + staging_ + " with the folder", e);
      // No RENAME_EXCHANGE here: the old set aside, then the new one in its place.
      old_set = beside(t, "old-" + pid_text());
      if ((e = do_rename(st, "rename aside", target_, old_set))) fail("cannot rename the folder aside to " + old_set, e);
      if ((e = do_rename(st, "rename into place", staging_, target_))) {
        const int back = do_rename(st, "rename back", old_set, target_);
        if (back)
          throw OutputError("output_dir '" + dir_ + "': cannot rename the new set into place (" + errno_text(e) +
                            ") nor the old one back (" + errno_text(back) + "): the earlier contents are in " + old_set +
                            " (the next run into the folder moves them back)");
        fail("cannot rename " + staging_ + " into place", e);
      }
    }
    committed_ = true;
    unregister_temp(slot_);
    slot_ = -1;
    if (had_old) {
      // Entries the user added to the old folder while the run carried it over: moved along.
      for (const auto& e : fs::directory_iterator(old_set, ec)) {
        const std::string n = e.path().filename().string();
        if (products.count(n) || legacy_temporary(n) || std::count(owned_.begin(), owned_.end(), n) ||
            fs::exists(fs::symlink_status(t / n, ec)))
          continue;
        if (st.next("move late entry") == 0) std::rename(e.path().c_str(), (t / n).c_str());
      }
      ec.clear();
      if (st.next("remove the old set") == 0) fs::remove_all(old_set, ec);
      else ec = std::make_error_code(std::errc::io_error);
      if (ec)
        std::cerr << "warning: output_dir '" << dir_ << "': the new outputs are in place, but the earlier set in "
                  << old_set << " could not be removed (" << ec.message() << "); the next run into the folder removes it\n";
    }
  }
}

// ---- StagedFiles -----------------------------------------------------------------------------

StagedFiles::~StagedFiles() {
  for (auto& it : items_) {
    if (!committed_) ::unlink(it.tmp.c_str());
    unregister_temp(it.slot);
  }
}

std::string StagedFiles::add(const std::string& key, const std::string& final_path) {
  check_output_path(key, final_path);
  Item it;
  const fs::path t = output_target(final_path);
  it.fin = t.string();
  for (const auto& o : items_)
    if (o.fin == it.fin) throw ConfigError(key + ": '" + final_path + "' is already another output of this command");
  std::error_code ec;
  const std::string what = key == final_path ? final_path : key + ": " + final_path;
  if (!fs::is_directory(t.parent_path(), ec))
    throw OutputError(what + ": " + t.parent_path().string() +
                      (fs::exists(t.parent_path(), ec) ? " is not a folder" : ": no such folder"));
  if (fs::is_directory(fs::symlink_status(t, ec))) throw OutputError(what + " is a folder");
  it.lock = std::make_unique<OutputLock>(it.fin);
  // Holding the lock: temporaries of this output left by killed processes go.
  const std::string prefix = "." + t.filename().string() + ".pcdp-tmp-";
  for (const auto& e : fs::directory_iterator(t.parent_path(), ec)) {
    const std::string n = e.path().filename().string();
    if (n.rfind(prefix, 0) == 0) fs::remove(e.path(), ec);
  }
  it.tmp = beside(t, "tmp-" + pid_text());
  const BlockSignals hold;
  const int fd = ::open(it.tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0)
    throw OutputError(what + ": cannot write in " + t.parent_path().string() + " (" + errno_text(errno) + ")");
  ::close(fd);
  it.slot = register_temp(it.tmp, 1);
  items_.push_back(std::move(it));
  return items_.back().tmp;
}

void StagedFiles::commit() {
  Steps st;
  std::error_code ec;
  enum class How { kNew, kExchanged, kBackup };
  std::vector<How> done;
  std::vector<std::string> backups;
  SwapGuard guard;
  const auto undo = [&] {
    for (std::size_t i = done.size(); i-- > 0;) {
      const Item& it = items_[i];
      if (done[i] == How::kNew) std::rename(it.fin.c_str(), it.tmp.c_str());
      else if (done[i] == How::kExchanged)
        ::syscall(SYS_renameat2, AT_FDCWD, it.tmp.c_str(), AT_FDCWD, it.fin.c_str(), RENAME_EXCHANGE);
      else std::rename(backups[i].c_str(), it.fin.c_str());
    }
  };
  for (const Item& it : items_) {
    backups.push_back(it.tmp + "-old");
    int e = 0;
    if (!fs::exists(fs::symlink_status(it.fin, ec))) {
      e = do_rename(st, "rename into place", it.tmp, it.fin);
      if (!e) done.push_back(How::kNew);
    } else {
      e = do_exchange(st, "exchange", it.tmp, it.fin);
      if (!e) done.push_back(How::kExchanged);
      else if (exchange_unsupported(e)) {
        e = st.next("back up");
        if (!e && ::link(it.fin.c_str(), backups.back().c_str()) != 0) e = errno;
        if (!e) e = do_rename(st, "rename into place", it.tmp, it.fin);
        if (!e) done.push_back(How::kBackup);
        else ::unlink(backups.back().c_str());
      }
    }
    if (e) {
      undo();
      throw OutputError(it.fin + ": cannot move the new file into place (" + errno_text(e) +
                        "); every output keeps its earlier contents");
    }
  }
  committed_ = true;
  for (std::size_t i = 0; i < items_.size(); ++i) {  // the old files, now under the temporary names
    if (done[i] == How::kExchanged) ::unlink(items_[i].tmp.c_str());
    if (done[i] == How::kBackup) ::unlink(backups[i].c_str());
  }
}

ScratchFolder::ScratchFolder(std::string path) : path_(std::move(path)) {
  remove_tree(path_);
  const BlockSignals hold;  // registered for the signal cleanup before a signal can act
  std::error_code ec;
  fs::create_directories(path_, ec);
  if (ec) throw OutputError("cannot create the scratch folder " + path_ + " (" + ec.message() + ")");
  slot_ = register_temp(path_, 2);
}

ScratchFolder::~ScratchFolder() {
  std::error_code ec;
  fs::remove_all(path_, ec);
  unregister_temp(slot_);
}

void write_file_atomic(const std::string& path, const std::string& content) {
  StagedFiles files;
  const std::string tmp = files.add(path, path);
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  const bool ok = f && std::fwrite(content.data(), 1, content.size(), f) == content.size();
  const int e = errno;
  if (f && std::fclose(f) != 0 && ok) throw OutputError(path + ": cannot write (" + errno_text(errno) + ")");
  if (!ok) throw OutputError(path + ": cannot write (" + errno_text(e) + ")");
  files.commit();
}

}  // namespace pcdp::io
