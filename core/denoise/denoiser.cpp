#include "core/denoise/denoiser.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

#include <tbb/task_arena.h>

#include "core/features/features.h"
#include "core/util/error.h"

namespace residue {
namespace {

// Largest tile edge tried when none is given: big tiles waste less on halos, but progress comes per tile.
constexpr int64_t kMaxAutoTile = 1024;

size_t tile_bytes(const nn::Backend& backend, const nn::Architecture& arch, int64_t tile) {
  const int64_t e = tile + 2 * arch.halo();
  const size_t pixels = static_cast<size_t>(e * e);
  return backend.scratch_bytes(e, e) + pixels * static_cast<size_t>(arch.in_channels() + 3) * sizeof(float);
}

bool colour_is_empty(const Image& colour, const Rect& r) {
  for (int64_t y = r.y; y < r.y + r.height; ++y)
    for (int64_t x = r.x; x < r.x + r.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const float v = colour.at(x, y, c);
        if (std::isfinite(v) && v > 0.0f) return false;
      }
  return true;
}

Rect expand(const Rect& r, int64_t halo, const Rect& bounds) {
  const int64_t x0 = std::max(bounds.x, r.x - halo), y0 = std::max(bounds.y, r.y - halo);
  const int64_t x1 = std::min(bounds.x + bounds.width, r.x + r.width + halo);
  const int64_t y1 = std::min(bounds.y + bounds.height, r.y + r.height + halo);
  return {x0, y0, x1 - x0, y1 - y0};
}

}  // namespace

std::vector<Rect> make_tiles(const Rect& region, int64_t tile) {
  std::vector<Rect> tiles;
  for (int64_t y = region.y; y < region.y + region.height; y += tile)
    for (int64_t x = region.x; x < region.x + region.width; x += tile)
      tiles.push_back({x, y, std::min(tile, region.x + region.width - x), std::min(tile, region.y + region.height - y)});
  return tiles;
}

int64_t tile_for_memory(const nn::Backend& backend, const nn::Architecture& arch, size_t budget) {
  for (int64_t t = kMaxAutoTile; t >= 16; t = t * 3 / 4)
    if (tile_bytes(backend, arch, t) <= budget) return t;
  return 0;
}

Image denoise(const AovStack& stack, const nn::Model& model, const DenoiseOptions& options, const TileCallback& on_tile,
              DenoiseStats* stats) {
  const auto start = std::chrono::steady_clock::now();
  const nn::Architecture& arch = model.network.arch;
  check_features_available(stack, arch.features);
  const Rect bounds{0, 0, stack.width(), stack.height()};
  const Rect region = options.roi.value_or(bounds);
  if (region.empty() || !bounds.contains(region))
    throw Error(ErrorKind::Usage, "the region " + region.to_string() + " is not inside the " +
                                      std::to_string(stack.width()) + "x" + std::to_string(stack.height()) + " image");

  std::string backend_name = options.backend;
  if (backend_name.empty()) backend_name = nn::available_backends().back();  // the last is the fastest
  const int threads = options.threads > 0 ? options.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);

  Image output = stack.color.image;  // outside the region the noisy colour stays

  DenoiseStats local;
  arena.execute([&] {
    auto backend = nn::make_backend(backend_name, model.network, {options.precision});
    const size_t output_bytes = output.size() * sizeof(float);
    const size_t budget = options.max_memory > output_bytes ? options.max_memory - output_bytes : 0;
    int64_t tile = options.tile;
    if (tile <= 0) {
      tile = tile_for_memory(*backend, arch, budget);
      if (tile == 0)
        throw Error(ErrorKind::Usage, "--max-memory " + std::to_string(options.max_memory >> 20) +
                                          " MiB is too small even for 16-pixel tiles of this model");
      tile = std::min(tile, std::max(region.width, region.height));
    } else if (tile_bytes(*backend, arch, tile) > budget) {
      throw Error(ErrorKind::Usage, "tiles of " + std::to_string(tile) + " px need " +
                                        std::to_string(tile_bytes(*backend, arch, tile) >> 20) +
                                        " MiB, over --max-memory; use smaller tiles or more memory");
    }
    const FeatureStats fstats = compute_feature_stats(stack);
    const std::vector<Rect> tiles = make_tiles(region, tile);
    local.tiles = static_cast<int64_t>(tiles.size());
    local.tile_size = tile;
    local.backend = backend->description();
    local.features = arch.features;

    Image features, result;
    for (size_t i = 0; i < tiles.size(); ++i) {
      const Rect& t = tiles[i];
      const Rect in = expand(t, arch.halo(), bounds);
      const bool skip = options.skip_empty_tiles && colour_is_empty(stack.color.image, in);
      if (skip) {
        ++local.skipped;
        for (int64_t y = t.y; y < t.y + t.height; ++y)
          std::memset(&output.at(t.x, y, 0), 0, static_cast<size_t>(t.width * 3) * sizeof(float));
      } else {
        make_features(stack, arch.features, fstats, in, features);
        backend->run(features, result);
        for (int64_t y = 0; y < t.height; ++y)
          for (int64_t x = 0; x < t.width; ++x)
            for (int c = 0; c < 3; ++c)
              output.at(t.x + x, t.y + y, c) = expand_color(result.at(t.x - in.x + x, t.y - in.y + y, c));
      }
      if (on_tile && !on_tile({t, skip, static_cast<int64_t>(i + 1), local.tiles}, output)) throw Cancelled();
    }
  });
  local.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (stats) *stats = local;
  return output;
}

}  // namespace residue
