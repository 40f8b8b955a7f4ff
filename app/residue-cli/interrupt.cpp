#include "interrupt.h"

#include <fcntl.h>
#include <poll.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <stdexcept>

#include "core/io/atomic_file.h"

namespace residue::cli {
namespace {

// One scope at a time: the handler reaches it through these (lock-free atomics and write(), all
// async-signal-safe).
CancelToken g_token;
std::atomic<int> g_signal{0};
std::atomic<int> g_wake_fd{-1};

constexpr char kSignalled = 's', kQuit = 'q';
// SIGHUP too: a dropped ssh session ends a run like a SIGTERM, its temporary file removed.
constexpr int kSignals[] = {SIGINT, SIGTERM, SIGHUP};

extern "C" void on_signal(int sig) {
  int expected = 0;
  g_signal.compare_exchange_strong(expected, sig);
  g_token.request();
  const int fd = g_wake_fd.load();
  if (fd >= 0) {
    const int saved = errno;
    [[maybe_unused]] const ssize_t n = ::write(fd, &kSignalled, 1);
    errno = saved;
  }
}

void set_handler(int sig, void (*handler)(int)) {
  struct sigaction sa {};
  sa.sa_handler = handler;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: a blocking read returns, the work sees the token soon after
  ::sigaction(sig, &sa, nullptr);
}

}  // namespace

InterruptScope::InterruptScope(std::chrono::milliseconds grace) {
  if (::pipe2(wake_, O_CLOEXEC) != 0) throw std::runtime_error("cannot create the interrupt pipe");
  g_token.reset();
  g_signal = 0;
  g_wake_fd = wake_[1];
  watchdog_ = std::thread(&InterruptScope::watch, this, grace);
  for (int sig : kSignals) set_handler(sig, on_signal);
}

InterruptScope::~InterruptScope() {
  for (int sig : kSignals) set_handler(sig, SIG_DFL);
  g_wake_fd = -1;
  [[maybe_unused]] const ssize_t n = ::write(wake_[1], &kQuit, 1);
  watchdog_.join();
  ::close(wake_[0]);
  ::close(wake_[1]);
}

const CancelToken& InterruptScope::token() const { return g_token; }

int InterruptScope::signal() const { return g_signal.load(); }

void InterruptScope::watch(std::chrono::milliseconds grace) {
  char c = 0;
  while (::read(wake_[0], &c, 1) < 0 && errno == EINTR) {
  }
  if (c != kSignalled) return;
  // The work has `grace` to unwind by itself; the scope's end (kQuit) means it did.
  pollfd p{wake_[0], POLLIN, 0};
  const auto deadline = std::chrono::steady_clock::now() + grace;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) break;
    const int ready = ::poll(&p, 1, static_cast<int>(left.count()));
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) break;
    if (::read(wake_[0], &c, 1) == 1 && c == kQuit) return;
    break;  // a second signal: stop now
  }
  io::remove_temp_files_in_progress();
  std::fprintf(stderr, "\nresidue-cli: interrupted; stopped without writing an output\n");
  std::fflush(stderr);
  ::_exit(128 + g_signal.load());
}

}  // namespace residue::cli
