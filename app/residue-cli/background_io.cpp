#include "background_io.h"

#include <csignal>

#if defined(__linux__)
#include <pthread.h>
#include <sys/resource.h>
#include <unistd.h>
#include <sys/resource.h>
#include <unistd.h>
#include <cstdlib>
#include <string>
#endif

#include <tbb/task_arena.h>

namespace residue::cli {

BackgroundIo::BackgroundIo() : thread_(&BackgroundIo::run, this) {}

BackgroundIo::~BackgroundIo() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  thread_.join();
}

void BackgroundIo::enqueue(std::function<void()> task) {
  {
    std::lock_guard lock(mutex_);
    tasks_.push_back(std::move(task));
  }
  wake_.notify_one();
}

void BackgroundIo::run() {
#if defined(__linux__)
  sigset_t signals;
  sigemptyset(&signals);
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&signals, sig);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  // The lowest priority of the normal class (nice is per thread on Linux): measured against the idle class
  // (SCHED_IDLE), which the network's two busy cores starved, so that the next frame was read while the
  // network waited for it (docs/PERFORMANCE.md, "Sequences").
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 19);  // refused: the tasks run at the normal priority
#endif
  tbb::task_arena one_thread(1, 1);
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stopping_ || !tasks_.empty(); });
      if (stopping_) return;  // the tasks not started are dropped: their futures report a broken promise
      task = std::move(tasks_.front());
      tasks_.pop_front();
    }
    one_thread.execute(task);
  }
}

}  // namespace residue::cli
