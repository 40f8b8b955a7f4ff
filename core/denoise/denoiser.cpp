#include "core/denoise/denoiser.h"

#include <chrono>

#include <tbb/task_arena.h>

#include "core/denoise/method.h"
#include "core/denoise/method_registry.h"
#include "core/denoise/strength.h"

namespace residue {
namespace {

// A model the caller owns, as the shared pointer a method holds (not owning: the call outlives nothing).
std::shared_ptr<const nn::Model> borrowed(const nn::Model& model) {
  return std::shared_ptr<const nn::Model>(std::shared_ptr<const nn::Model>(), &model);
}

int threads_of(const DenoiseOptions& o) {
  return o.threads > 0 ? o.threads : tbb::this_task_arena::max_concurrency();
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

nn::Backend& BackendCache::get(const nn::Model& model, const std::string& backend, nn::Precision precision) {
  auto& slot = backends_[{&model, backend, precision}];
  if (!slot) slot = nn::make_backend(backend, model.graph, {precision});
  return *slot;
}

float variance_blend_tau(const DenoiseOptions& options, const nn::Model& model) {
  return make_method(borrowed(model))->variance_blend_tau(options);
}

Image denoise(const AovStack& stack, const Method& method, const DenoiseOptions& options, const TileCallback& on_tile,
              DenoiseStats* stats) {
  const auto start = std::chrono::steady_clock::now();
  check_strength(options.strength);
  tbb::task_arena arena(threads_of(options));
  DenoiseStats local;
  Image output;
  arena.execute([&] {
    WorkCounter work{0, method.work(stack.width(), stack.height(), options)};
    output = method.denoise(stack, options, on_tile, local, work);
  });
  local.seconds = seconds_since(start);
  if (stats) *stats = local;
  return output;
}

Image denoise(const AovStack& stack, const nn::Model& model, const DenoiseOptions& options, const TileCallback& on_tile,
              DenoiseStats* stats) {
  return denoise(stack, *make_method(borrowed(model)), options, on_tile, stats);
}

DenoiseStats denoise_to_exr(const AovReader& reader, const Method& method, const DenoiseOptions& options,
                            const std::filesystem::path& output, io::ExrWriteOptions exr, const TileCallback& on_tile) {
  const auto start = std::chrono::steady_clock::now();
  check_strength(options.strength);
  const AovStack& layout = reader.layout();
  const int64_t W = layout.data_window.width, H = layout.data_window.height;
  checked_region(options, W, H);  // before any work
  if (exr.data_window.empty()) exr.data_window = layout.data_window;
  if (exr.display_width <= 0) exr.display_width = layout.display_width;
  if (exr.display_height <= 0) exr.display_height = layout.display_height;
  if (exr.metadata.empty()) exr.metadata = layout.metadata;
  tbb::task_arena arena(threads_of(options));
  DenoiseStats local;
  arena.execute([&] {
    WorkCounter work{0, method.work(W, H, options)};
    local = method.denoise_to_exr(reader, options, output, std::move(exr), on_tile, work);
  });
  local.seconds = seconds_since(start);
  return local;
}

DenoiseStats denoise_to_exr(const AovReader& reader, const nn::Model& model, const DenoiseOptions& options,
                            const std::filesystem::path& output, io::ExrWriteOptions exr, const TileCallback& on_tile) {
  return denoise_to_exr(reader, *make_method(borrowed(model)), options, output, std::move(exr), on_tile);
}

}  // namespace residue
