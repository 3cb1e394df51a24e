// The signal cleanup of the staged outputs, for atomic_file.cpp (internal): temporaries are
// registered while they exist, so that SIGINT, SIGTERM or SIGHUP removes them before the process
// exits (install_signal_cleanup, pcdp/io/atomic_file.hpp).
#pragma once

#include <pthread.h>

#include <csignal>
#include <string>

namespace pcdp::io::cleanup {

/// Registers a temporary for removal on a signal: kind 1 a file (and the temporaries its writers
/// make beside it), 2 a folder tree. Returns its slot, or -1 when the table is full (the next run
/// into the folder removes the leftovers).
int register_temp(const std::string& path, int kind);
/// Forgets a slot (-1: nothing).
void unregister_temp(int slot);

/// Holds SIGINT, SIGTERM and SIGHUP back in this thread while a temporary is created and
/// registered (a signal between the two would leave it behind); they arrive at the end.
struct BlockSignals {
  sigset_t old;
  BlockSignals() {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    sigaddset(&set, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &set, &old);
  }
  ~BlockSignals() { pthread_sigmask(SIG_SETMASK, &old, nullptr); }
};

/// Marks a commit's swap: signals wait for its end.
struct SwapGuard {
  SwapGuard();
  ~SwapGuard();
  SwapGuard(const SwapGuard&) = delete;
  SwapGuard& operator=(const SwapGuard&) = delete;
};

}  // namespace pcdp::io::cleanup
