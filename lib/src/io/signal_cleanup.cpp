// The signal cleanup of the staged outputs (pcdp/io/atomic_file.hpp): a fixed table of the
// temporaries in flight that the SIGINT/SIGTERM/SIGHUP handler reads without locks or allocation,
// and removes before the process exits; a commit's swap holds the signal back until it is done.
#include "io/signal_cleanup.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>

#include "pcdp/io/atomic_file.hpp"

namespace pcdp::io {

namespace {

constexpr int kSlots = 16;
constexpr std::size_t kPathMax = 4096;
struct Slot {
  std::atomic<int> kind{0};  // 0 free, 1 file, 2 folder tree, -1 being filled
  char path[kPathMax];
};
Slot g_slots[kSlots];
std::atomic<int> g_committing{0};      // swaps in progress: a signal waits for their end
std::atomic<int> g_pending_signal{0};

// Removes a folder tree with system calls only (async-signal-safe): getdents64, unlinkat.
void remove_tree_at(int parent, const char* name, int depth) {
  if (::unlinkat(parent, name, 0) == 0 || (errno != EISDIR && errno != EPERM)) return;
  if (depth > 16) return;
  const int fd = ::openat(parent, name, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) return;
  alignas(8) char buf[2048];
  for (int round = 0; round < 64; ++round) {
    bool removed = false;
    ::lseek(fd, 0, SEEK_SET);
    for (;;) {
      const long n = ::syscall(SYS_getdents64, fd, buf, sizeof buf);
      if (n <= 0) break;
      for (long off = 0; off < n;) {
        // struct linux_dirent64: u64 ino, s64 off, u16 reclen, u8 type, char name[]
        unsigned short reclen;
        std::memcpy(&reclen, buf + off + 16, sizeof reclen);
        const char* entry = buf + off + 19;
        off += reclen;
        if (entry[0] == '.' && (entry[1] == 0 || (entry[1] == '.' && entry[2] == 0))) continue;
        remove_tree_at(fd, entry, depth + 1);
        removed = true;
      }
    }
    if (!removed) break;
  }
  ::close(fd);
  ::unlinkat(parent, name, AT_REMOVEDIR);
}

void remove_registered() {
  for (auto& s : g_slots) {
    const int k = s.kind.load();
    if (k == 1) {  // the file, and the temporaries its writers make beside it (pcd.cpp, geotiff.cpp)
      ::unlink(s.path);
      const std::size_t n = std::strlen(s.path);
      for (const char* suffix : {".body", ".tmp-write.tif", ".tmp-png"}) {
        char p[kPathMax + 16];
        const std::size_t m = std::strlen(suffix);
        if (n + m >= sizeof p) continue;
        std::memcpy(p, s.path, n);
        std::memcpy(p + n, suffix, m + 1);
        ::unlink(p);
      }
    }
    if (k == 2) remove_tree_at(AT_FDCWD, s.path, 0);
  }
}

extern "C" void on_signal(int sig) {
  if (g_committing.load() > 0) {  // a swap is under way: it finishes, then the signal is acted on
    g_pending_signal.store(sig);
    return;
  }
  remove_registered();
  ::_exit(128 + sig);
}

}  // namespace

namespace cleanup {

int register_temp(const std::string& path, int kind) {
  if (path.size() >= kPathMax) return -1;
  for (int i = 0; i < kSlots; ++i) {
    int expected = 0;
    if (g_slots[i].kind.compare_exchange_strong(expected, -1)) {
      std::memcpy(g_slots[i].path, path.c_str(), path.size() + 1);
      g_slots[i].kind.store(kind);
      return i;
    }
  }
  return -1;  // full: the next run into the folder removes the leftovers
}
void unregister_temp(int slot) {
  if (slot >= 0) g_slots[slot].kind.store(0);
}

SwapGuard::SwapGuard() { g_committing.fetch_add(1); }
SwapGuard::~SwapGuard() {
  if (g_committing.fetch_sub(1) == 1) {
    const int sig = g_pending_signal.exchange(0);
    if (sig) on_signal(sig);
  }
}

}  // namespace cleanup

void install_signal_cleanup() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaction(sig, &sa, nullptr);
}

}  // namespace pcdp::io
