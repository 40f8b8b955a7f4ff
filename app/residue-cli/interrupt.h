// SIGINT, SIGTERM and SIGHUP during a long command. The first signal raises a CancelToken that the work checks
// between network layers; the work unwinds (removing its temporary file) and the command exits 130 (SIGINT),
// 143 (SIGTERM) or 129 (SIGHUP). Where the work cannot stop that soon (inside one oneDNN primitive, or while a file is written), a
// watchdog removes the temporary files in progress and ends the process after a grace period, with the same
// exit code; a second signal does so at once. So an interrupted run stops within about a second and leaves no
// file behind.
#pragma once

#include <chrono>
#include <thread>

#include "core/util/cancel.h"

namespace residue::cli {

class InterruptScope {
 public:
  explicit InterruptScope(std::chrono::milliseconds grace = std::chrono::milliseconds(800));
  ~InterruptScope();  // restores the default handlers
  InterruptScope(const InterruptScope&) = delete;
  InterruptScope& operator=(const InterruptScope&) = delete;

  const CancelToken& token() const;
  bool interrupted() const { return signal() != 0; }
  int signal() const;                            // 0 until a signal arrives
  int exit_code() const { return 128 + signal(); }  // 130 for SIGINT, 143 for SIGTERM, 129 for SIGHUP

 private:
  void watch(std::chrono::milliseconds grace);
  int wake_[2] = {-1, -1};  // the handler writes a byte here to wake the watchdog
  std::thread watchdog_;
};

}  // namespace residue::cli
