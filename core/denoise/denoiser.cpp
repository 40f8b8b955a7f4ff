#include "core/denoise/denoiser.h"

#include <chrono>
#include <cmath>

#include <tbb/task_arena.h>

#include "core/denoise/converged_regions.h"
#include "core/denoise/method.h"
#include "core/denoise/method_registry.h"
#include "core/denoise/strength.h"
#include "core/util/error.h"

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

// skip_converged: the method on the plan's rectangles only, each faded into the noisy colour by the plan's weight
// (converged_regions.h). A plan of one rectangle, the whole region, is the ordinary denoise, bit for bit.
Image denoise_where_needed(const AovStack& stack, const Method& method, const DenoiseOptions& options,
                           const TileCallback& on_tile, DenoiseStats& stats) {
  const int64_t W = stack.width(), H = stack.height();
  if (!(options.skip_converged > 0) || !std::isfinite(options.skip_converged))
    throw Error(ErrorKind::Usage, "--skip-converged " + std::to_string(options.skip_converged) +
                                      ": give a relative variance above 0 (such as 1e-4)");
  if (!stack.variance)
    throw Error(ErrorKind::Input, "--skip-converged: '" + stack.color.source.file + "' has no variance AOV, so "
                                  "nothing says where it has converged (a variance pass, or the two halves of a render)");
  const Rect region = checked_region(options, W, H);
  const int64_t halo = method.model() ? method.model()->graph.halo() : 0;
  const ConvergedPlan plan = plan_converged(stack, region, options.skip_converged, halo);
  DenoiseOptions each = options;
  each.skip_converged = 0;
  if (plan.regions.size() == 1 && plan.regions.front() == region) {
    WorkCounter work{0, method.work(W, H, each)};
    Image out = method.denoise(stack, each, on_tile, stats, work);
    stats.skip_converged = options.skip_converged;
    stats.network_pixels = plan.network_pixels;
    return out;
  }
  WorkCounter work{0, 0};
  for (const Rect& r : plan.regions) {
    each.roi = r;
    work.total += method.work(W, H, each);
  }
  Image out(W, H, 3);
  for (int64_t y = 0; y < H; ++y)
    for (int64_t x = 0; x < W; ++x)
      for (int c = 0; c < 3; ++c) out.at(x, y, c) = stack.color.image.at(x, y, c);
  bool first = true;
  std::vector<uint8_t> blended(static_cast<size_t>(region.area()), 0);  // rectangles may overlap: blend once
  for (const Rect& r : plan.regions) {
    each.roi = r;
    DenoiseStats s;
    const Image den = method.denoise(stack, each, on_tile, s, work);
    for (int64_t y = r.y; y < r.y + r.height; ++y)
      for (int64_t x = r.x; x < r.x + r.width; ++x) {
        uint8_t& done = blended[static_cast<size_t>((y - region.y) * region.width + (x - region.x))];
        if (done) continue;
        done = 1;
        const float w = plan.weight.at(x - region.x, y - region.y, 0);
        for (int c = 0; c < 3; ++c) out.at(x, y, c) += w * (den.at(x, y, c) - out.at(x, y, c));
      }
    if (first) stats = s;
    else stats.tiles += s.tiles, stats.skipped += s.skipped, stats.guarded_values += s.guarded_values;
    first = false;
  }
  if (first) {  // all converged: nothing ran; the stats say what would have
    stats.features = method.features();
    stats.strength = options.strength;
  }
  stats.skip_converged = options.skip_converged;
  stats.converged_pixels = plan.kept_pixels;
  stats.regions = static_cast<int64_t>(plan.regions.size());
  stats.network_pixels = plan.network_pixels;
  return out;
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
    if (options.skip_converged != 0) {
      output = denoise_where_needed(stack, method, options, on_tile, local);
      return;
    }
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
  if (options.skip_converged != 0)
    throw Error(ErrorKind::Usage, "--skip-converged needs the render in memory, and '" + layout.color.source.file +
                                      "' is streamed band by band: raise --max-memory to hold it");
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
