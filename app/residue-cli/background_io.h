// The reading and writing a sequence does beside its network: frame n+1 read and frame n-1 written while frame
// n is denoised (denoise_sequence.cpp).
//
// On 2 cores the network already keeps both busy, and a thread that takes a core from one of its parallel
// regions stretches the region to its slowest thread. So the tasks run one at a time, in order, on one thread
// at the lowest priority (nice 19: the network's threads get the cores whenever they want them), inside a
// one-thread oneTBB arena (their parallel loops stay on this thread, off the network's workers), with the
// interrupt signals blocked (they go to the main thread, and a file's read or write is not cut short by EINTR).
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <thread>

namespace residue::cli {

class BackgroundIo {
 public:
  BackgroundIo();
  // Lets the task in progress finish and drops the ones not started: wait for the futures you need first.
  ~BackgroundIo();
  BackgroundIo(const BackgroundIo&) = delete;
  BackgroundIo& operator=(const BackgroundIo&) = delete;

  // Queues `task`; its result (or its exception) arrives in the future.
  template <class F>
  auto submit(F task) -> std::future<decltype(task())> {
    auto packaged = std::make_shared<std::packaged_task<decltype(task())()>>(std::move(task));
    std::future<decltype(task())> result = packaged->get_future();
    enqueue([packaged] { (*packaged)(); });
    return result;
  }

 private:
  void enqueue(std::function<void()> task);
  void run();

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> tasks_;
  bool stopping_ = false;
  std::thread thread_;  // last: started when the queue exists
};

}  // namespace residue::cli
