// Stopping long work early: a flag that another thread, or a signal handler, raises, and that the work checks
// between small steps (tiles, network layers, rows of a convolution) so that it stops within a fraction of a
// second whatever the tile size.
#pragma once

#include <atomic>
#include <cstdint>
#include <stdexcept>

namespace residue {

// Thrown by work that saw its token raised (or whose tile callback asked to stop).
class Cancelled : public std::runtime_error {
 public:
  Cancelled() : std::runtime_error("denoise cancelled") {}
};

class CancelToken {
 public:
  // Safe in a signal handler: a lock-free atomic store.
  void request() noexcept { flag_.store(true, std::memory_order_relaxed); }
  void reset() noexcept { flag_.store(false, std::memory_order_relaxed); }
  bool requested() const noexcept {
    checks_.fetch_add(1, std::memory_order_relaxed);
    return flag_.load(std::memory_order_relaxed);
  }
  // How often the work has looked at the token so far: lets a test wait until the work is inside a step (a
  // tile's layers) before it cancels, instead of sleeping and hoping.
  int64_t checks() const noexcept { return checks_.load(std::memory_order_relaxed); }

 private:
  std::atomic<bool> flag_{false};
  mutable std::atomic<int64_t> checks_{0};
  static_assert(std::atomic<bool>::is_always_lock_free);
};

// Throws Cancelled when `token` is set and raised.
inline void throw_if_cancelled(const CancelToken* token) {
  if (token != nullptr && token->requested()) throw Cancelled();
}

}  // namespace residue
