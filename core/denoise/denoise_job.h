// A denoise on a worker thread, for viewers and services: start it, watch progress and finished tiles,
// cancel it at any time, and get the result or the error as a value.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "core/denoise/denoiser.h"
#include "core/denoise/method.h"
#include "core/util/error.h"

namespace residue {

class DenoiseJob {
 public:
  enum class Status { Running, Done, Cancelled, Failed };

  struct Progress {
    int64_t done = 0;   // tiles of the pass running
    int64_t total = 0;
    int64_t skipped = 0;
    int64_t work_done = 0, work_total = 0;  // every pass: the fraction to show
    bool preliminary = false;  // the pass running prepares the result (a prefilter, a prior)
    double fraction() const {
      return work_total > 0 ? static_cast<double>(work_done) / static_cast<double>(work_total) : 0.0;
    }
  };

  // Called on the worker thread after each tile of the result with the tile's rectangle and its denoised pixels
  // (a copy the receiver may keep); a prefilter's or prior's tiles only move the progress. Keep it short: the
  // next tile waits for it.
  using TileReady = std::function<void(const Rect& rect, const Image& pixels)>;

  // Starts at once. The stack and method are shared so the caller may drop its references.
  DenoiseJob(std::shared_ptr<const AovStack> stack, std::shared_ptr<const Method> method, DenoiseOptions options,
             TileReady on_tile = {});
  // The method that runs `model` (method_registry.h).
  DenoiseJob(std::shared_ptr<const AovStack> stack, std::shared_ptr<const nn::Model> model, DenoiseOptions options,
             TileReady on_tile = {});
  ~DenoiseJob();  // cancels and waits
  DenoiseJob(const DenoiseJob&) = delete;
  DenoiseJob& operator=(const DenoiseJob&) = delete;

  Progress progress() const;
  Status status() const;
  // Asks the worker to stop; it does so within one network layer. Returns at once.
  void cancel();
  // Waits until the job ends or `timeout` passes; true when it has ended.
  bool wait_for(std::chrono::milliseconds timeout);
  void wait();

  // After Done: the denoised colour and what it took. After Failed: the error. Empty otherwise.
  const std::optional<Image>& result() const { return result_; }
  const DenoiseStats& stats() const { return stats_; }
  const std::string& error() const { return error_; }
  const Method& method() const { return *method_; }  // what runs (or ran)
  std::optional<ErrorKind> error_kind() const { return error_kind_; }

 private:
  void work(std::shared_ptr<const AovStack> stack, std::shared_ptr<const Method> method, DenoiseOptions options,
            TileReady on_tile);

  std::shared_ptr<const Method> method_;
  CancelToken cancel_;
  std::atomic<int64_t> done_{0}, total_{0}, skipped_{0}, work_done_{0}, work_total_{0};
  std::atomic<bool> preliminary_{false};
  std::atomic<Status> status_{Status::Running};
  mutable std::mutex mutex_;
  std::condition_variable ended_;
  std::optional<Image> result_;
  DenoiseStats stats_;
  std::string error_;
  std::optional<ErrorKind> error_kind_;
  std::thread worker_;  // last: starts after every member above exists
};

}  // namespace residue
