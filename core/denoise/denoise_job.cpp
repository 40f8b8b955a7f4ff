#include "core/denoise/denoise_job.h"

#include "core/denoise/method_registry.h"

namespace residue {

DenoiseJob::DenoiseJob(std::shared_ptr<const AovStack> stack, std::shared_ptr<const Method> method,
                       DenoiseOptions options, TileReady on_tile)
    : method_(method),
      worker_(&DenoiseJob::work, this, std::move(stack), std::move(method), std::move(options), std::move(on_tile)) {}

DenoiseJob::DenoiseJob(std::shared_ptr<const AovStack> stack, std::shared_ptr<const nn::Model> model,
                       DenoiseOptions options, TileReady on_tile)
    : DenoiseJob(std::move(stack), std::shared_ptr<const Method>(make_method(std::move(model))), std::move(options),
                 std::move(on_tile)) {}

DenoiseJob::~DenoiseJob() {
  cancel();
  if (worker_.joinable()) worker_.join();
}

void DenoiseJob::work(std::shared_ptr<const AovStack> stack, std::shared_ptr<const Method> method,
                      DenoiseOptions options, TileReady on_tile) {
  Status end = Status::Done;
  options.cancel = &cancel_;
  try {
    DenoiseStats stats;
    Image out = denoise(
        *stack, *method, options,
        [&](const TileEvent& e, const Image& pixels) {
          done_ = e.done;
          total_ = e.total;
          work_done_ = e.work_done;
          work_total_ = e.work_total;
          preliminary_ = !e.result;
          if (e.skipped) ++skipped_;
          if (on_tile && e.result) on_tile(e.rect, pixels);
          return !cancel_.requested();
        },
        &stats);
    std::lock_guard lock(mutex_);
    result_ = std::move(out);
    stats_ = stats;
  } catch (const Cancelled&) {
    end = Status::Cancelled;
  } catch (const Error& e) {
    std::lock_guard lock(mutex_);
    error_ = e.what();
    error_kind_ = e.kind();
    end = Status::Failed;
  } catch (const std::exception& e) {
    std::lock_guard lock(mutex_);
    error_ = e.what();
    end = Status::Failed;
  }
  {
    std::lock_guard lock(mutex_);
    status_ = end;
  }
  ended_.notify_all();
}

DenoiseJob::Progress DenoiseJob::progress() const {
  return {done_.load(), total_.load(), skipped_.load(), work_done_.load(), work_total_.load(), preliminary_.load()};
}

DenoiseJob::Status DenoiseJob::status() const { return status_.load(); }

void DenoiseJob::cancel() { cancel_.request(); }

bool DenoiseJob::wait_for(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  return ended_.wait_for(lock, timeout, [&] { return status_.load() != Status::Running; });
}

void DenoiseJob::wait() {
  std::unique_lock lock(mutex_);
  ended_.wait(lock, [&] { return status_.load() != Status::Running; });
}

}  // namespace residue
