#include "core/denoise/denoiser.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <deque>

#include <tbb/task_arena.h>

#include "core/denoise/energy_correction.h"
#include "core/denoise/output_guard.h"
#include "core/denoise/variance_blend.h"
#include "core/features/features.h"
#include "core/io/exr_writer.h"
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

Rect expand(const Rect& r, int64_t halo, const Rect& bounds);

// The variance blend's tau for this denoise; 0 when it is off.
float tau_for(const DenoiseOptions& o, const nn::Model& model) {
  if (!o.variance_blend) return 0.0f;
  return o.blend_tau > 0 ? o.blend_tau : blend_tau(model.metadata);
}

// Denoises one tile. `src` holds the image's pixels of `src_rect` (image coordinates; it covers the tile and
// its halo); the result goes to `out` at the tile's position minus (out_x0, out_y0). Returns true when skipped.
struct TileRunner {
  const nn::Architecture& arch;
  nn::Backend& backend;
  const FeatureStats& stats;
  bool skip_empty;
  bool guard;       // clamp overshoots to the receptive field's brightest input (output_guard.h)
  float blend_tau;  // variance blend (when the stack has variance); 0: off
  int64_t guarded = 0;  // values the guard clamped so far
  Image features, result;

  bool run(const AovStack& src, const Rect& src_rect, const Rect& bounds, const Rect& t, Image& out, int64_t out_x0,
           int64_t out_y0) {
    Rect in = expand(t, arch.halo(), bounds);
    in.x -= src_rect.x;
    in.y -= src_rect.y;
    const int64_t tx = t.x - src_rect.x, ty = t.y - src_rect.y;
    if (skip_empty && colour_is_empty(src.color.image, in)) {
      for (int64_t y = t.y; y < t.y + t.height; ++y)
        std::memset(&out.at(t.x - out_x0, y - out_y0, 0), 0, static_cast<size_t>(t.width * 3) * sizeof(float));
      return true;
    }
    make_features(src, arch.features, stats, in, features);
    backend.run(features, result);
    if (guard) guarded += guard_output(features, {tx - in.x, ty - in.y, t.width, t.height}, arch.halo(), result);
    for (int64_t y = 0; y < t.height; ++y)
      for (int64_t x = 0; x < t.width; ++x)
        for (int c = 0; c < 3; ++c)
          out.at(t.x - out_x0 + x, t.y - out_y0 + y, c) = expand_color(result.at(tx - in.x + x, ty - in.y + y, c));
    if (blend_tau > 0 && src.variance) blend_by_variance(src, src_rect, bounds, t, out, out_x0, out_y0, blend_tau);
    return false;
  }
};

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
    const float tau = tau_for(options, model);
    local.variance_blended = tau > 0 && stack.variance.has_value();

    TileRunner runner{arch, *backend, fstats, options.skip_empty_tiles, options.output_guard, tau, 0, {}, {}};
    for (size_t i = 0; i < tiles.size(); ++i) {
      const bool skip = runner.run(stack, bounds, bounds, tiles[i], output, 0, 0);
      if (skip) ++local.skipped;
      if (on_tile && !on_tile({tiles[i], skip, static_cast<int64_t>(i + 1), local.tiles}, output)) throw Cancelled();
    }
    local.guarded_values = runner.guarded;
    if (options.energy_correction) {
      EnergyCorrection correction(region);
      correction.accumulate(stack.color.image, 0, output, 0, region.y, region.height);
      correction.apply(output, 0, region.y, region.height);
      local.energy_corrected = true;
    }
  });
  local.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (stats) *stats = local;
  return output;
}

DenoiseStats denoise_to_exr(const AovReader& reader, const nn::Model& model, const DenoiseOptions& options,
                            const std::filesystem::path& output, io::ExrWriteOptions exr, const TileCallback& on_tile) {
  const auto start = std::chrono::steady_clock::now();
  const AovStack& layout = reader.layout();
  const nn::Architecture& arch = model.network.arch;
  check_features_available(layout, arch.features);
  const int64_t W = layout.data_window.width, H = layout.data_window.height;
  const Rect bounds{0, 0, W, H};
  const Rect region = options.roi.value_or(bounds);
  if (region.empty() || !bounds.contains(region))
    throw Error(ErrorKind::Usage, "the region " + region.to_string() + " is not inside the " + std::to_string(W) +
                                      "x" + std::to_string(H) + " image");
  const int64_t stack_channels = layout.channel_count();  // floats per pixel of a band as read

  if (exr.data_window.empty()) exr.data_window = layout.data_window;
  if (exr.display_width <= 0) exr.display_width = layout.display_width;
  if (exr.display_height <= 0) exr.display_height = layout.display_height;
  if (exr.metadata.empty()) exr.metadata = layout.metadata;
  std::string backend_name = options.backend.empty() ? nn::available_backends().back() : options.backend;
  const int threads = options.threads > 0 ? options.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  DenoiseStats local;
  arena.execute([&] {
    auto backend = nn::make_backend(backend_name, model.network, {options.precision});
    const int64_t h = arch.halo();
    // The energy correction needs the denoised rows a few blocks below a band before it can finish the band,
    // so bands are denoised that far ahead of the one written.
    auto bands_ahead = [&](int64_t tile) {
      return options.energy_correction ? (EnergyCorrection::kBlock * (EnergyCorrection::kRadiusBlocks + 2) + tile - 1) / tile : 0;
    };
    const size_t correction_grid = options.energy_correction
                                       ? static_cast<size_t>((W / EnergyCorrection::kBlock + 1) * (H / EnergyCorrection::kBlock + 1)) *
                                             EnergyCorrection::kBytesPerBlock
                                       : 0;
    // Memory of one band of tile rows: its input rows with halos, its output rows (and those denoised ahead),
    // and one tile's work.
    auto band_bytes = [&](int64_t tile) {
      return static_cast<size_t>(((tile + 2 * h) * stack_channels + (1 + bands_ahead(tile)) * tile * 3) * W) * sizeof(float) +
             tile_bytes(*backend, arch, tile) + correction_grid;
    };
    int64_t tile = options.tile;
    if (tile <= 0)
      for (int64_t t = kMaxAutoTile; t >= 16 && tile <= 0; t = t * 3 / 4)
        if (band_bytes(t) <= options.max_memory) tile = t;
    if (tile <= 0 || band_bytes(tile) > options.max_memory)
      throw Error(ErrorKind::Usage, "--max-memory " + std::to_string(options.max_memory >> 20) + " MiB cannot hold a band of " +
                                        std::to_string(std::max<int64_t>(tile, 16)) + "-pixel tiles of this " +
                                        std::to_string(W) + "-pixel-wide image");
    local.tile_size = tile;
    local.backend = backend->description();
    local.features = arch.features;
    local.energy_corrected = options.energy_correction;
    const float tau = tau_for(options, model);
    local.variance_blended = tau > 0 && layout.variance.has_value();
    exr.residue_attributes.attribute("residue:backend", local.backend);
    exr.residue_attributes.attribute("residue:energy_correction", local.energy_corrected ? 1 : 0);
    exr.residue_attributes.attribute("residue:variance_blend", local.variance_blended ? 1 : 0);

    // Pass 1: the whole-image statistics the features need (the same depth sample denoise() draws).
    FeatureStats fstats = compute_feature_stats(layout);
    if (layout.depth) {
      const int64_t stride = depth_sample_stride(W * H);
      std::vector<float> samples;
      for (int64_t y0 = 0; y0 < H; y0 += tile) {
        const AovStack band = reader.read({0, y0, W, std::min(tile, H - y0)});
        for (int64_t i = 0; i < band.depth->image.pixel_count(); ++i)
          if ((y0 * W + i) % stride == 0) samples.push_back(band.depth->image.data()[i]);
      }
      fstats.depth_scale = depth_scale_from_samples(samples);
    }

    // Pass 2: bands of tile rows, denoised (ahead of writing when correcting) and written in order. Tiles sit
    // on the image's grid (so each lies in one band), cut to the region.
    std::vector<Rect> tiles;
    for (const Rect& t : make_tiles(bounds, tile)) {
      const int64_t x0 = std::max(t.x, region.x), y0 = std::max(t.y, region.y);
      const int64_t x1 = std::min(t.x + t.width, region.x + region.width);
      const int64_t y1 = std::min(t.y + t.height, region.y + region.height);
      if (x1 > x0 && y1 > y0) tiles.push_back({x0, y0, x1 - x0, y1 - y0});
    }
    local.tiles = static_cast<int64_t>(tiles.size());
    TileRunner runner{arch, *backend, fstats, options.skip_empty_tiles, options.output_guard, tau, 0, {}, {}};
    EnergyCorrection correction(region);
    int64_t done = 0;
    struct Band {
      int64_t y0;
      Image out;
    };
    std::deque<Band> denoised;  // bands denoised but not yet written
    int64_t denoised_end = 0;   // rows denoised so far
    auto denoise_band = [&](int64_t y0) {
      const int64_t rows = std::min(tile, H - y0);
      const int64_t in_y0 = std::max<int64_t>(0, y0 - h), in_y1 = std::min(H, y0 + rows + h);
      const Rect src_rect{0, in_y0, W, in_y1 - in_y0};
      const AovStack src = reader.read(src_rect);
      Image out = crop(src.color.image, {0, y0 - in_y0, W, rows});  // outside the region the noisy colour stays
      for (const Rect& t : tiles) {
        if (t.y < y0 || t.y >= y0 + rows) continue;
        const bool skip = runner.run(src, src_rect, bounds, t, out, 0, y0);
        if (skip) ++local.skipped;
        ++done;
        if (on_tile && !on_tile({t, skip, done, local.tiles}, out)) throw Cancelled();
      }
      if (options.energy_correction) correction.accumulate(src.color.image, in_y0, out, y0, y0, rows);
      denoised.push_back({y0, std::move(out)});
      denoised_end = y0 + rows;
    };
    io::write_exr_bands(output, W, H, 3, tile, exr, [&](int64_t y0, int64_t rows) {
      const int64_t needed = options.energy_correction ? std::max(y0 + rows, correction.rows_required(y0 + rows)) : y0 + rows;
      while (denoised_end < needed) denoise_band(denoised_end);
      Band band = std::move(denoised.front());
      denoised.pop_front();
      if (options.energy_correction) correction.apply(band.out, band.y0, y0, rows);
      return std::move(band.out);
    });
    local.guarded_values = runner.guarded;
  });
  local.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return local;
}

}  // namespace residue
