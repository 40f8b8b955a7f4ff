#include "core/denoise/engine/tiling.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/denoise/denoiser.h"
#include "core/util/error.h"

namespace residue {

std::vector<Rect> make_tiles(const Rect& region, int64_t tile) {
  std::vector<Rect> tiles;
  for (int64_t y = region.y; y < region.y + region.height; y += tile)
    for (int64_t x = region.x; x < region.x + region.width; x += tile)
      tiles.push_back({x, y, std::min(tile, region.x + region.width - x), std::min(tile, region.y + region.height - y)});
  return tiles;
}

std::vector<Rect> grid_tiles(const Rect& bounds, const Rect& region, int64_t tile) {
  std::vector<Rect> tiles;
  for (const Rect& t : make_tiles(bounds, tile)) {
    const int64_t x0 = std::max(t.x, region.x), y0 = std::max(t.y, region.y);
    const int64_t x1 = std::min(t.x + t.width, region.x + region.width);
    const int64_t y1 = std::min(t.y + t.height, region.y + region.height);
    if (x1 > x0 && y1 > y0) tiles.push_back({x0, y0, x1 - x0, y1 - y0});
  }
  return tiles;
}

Rect expand(const Rect& r, int64_t halo, const Rect& bounds, int64_t align) {
  const int64_t x0 = std::max(bounds.x, r.x - halo) / align * align, y0 = std::max(bounds.y, r.y - halo) / align * align;
  const int64_t x1 = std::min(bounds.x + bounds.width, r.x + r.width + halo);
  const int64_t y1 = std::min(bounds.y + bounds.height, r.y + r.height + halo);
  return {x0, y0, x1 - x0, y1 - y0};
}

int64_t align_tile(int64_t tile, int64_t align) { return std::max(align, tile / align * align); }

size_t tile_bytes(const nn::Backend& backend, const nn::Graph& graph, int64_t tile, int ensemble) {
  const int64_t a = graph.alignment();
  const int64_t e = (tile + 2 * graph.halo() + a - 1) / a * a;
  const size_t pixels = static_cast<size_t>(e * e);
  const int64_t planes = 2 * graph.input_channels() + graph.output_channels() +
                         (ensemble > 1 ? graph.input_channels() + 2 * graph.output_channels() : 0);
  return backend.scratch_bytes(e, e) + pixels * static_cast<size_t>(planes) * sizeof(float);
}

int64_t tile_for_memory(const nn::Backend& backend, const nn::Graph& graph, size_t budget, int ensemble) {
  for (int64_t t = kMaxAutoTile; t >= 16; t = t * 3 / 4) {
    const int64_t aligned = align_tile(t, graph.alignment());
    if (tile_bytes(backend, graph, aligned, ensemble) <= budget) return aligned;
  }
  return 0;
}

int64_t interactive_tile(const nn::Graph& graph, double seconds_per_mp, double target_seconds) {
  const int64_t a = graph.alignment(), halo = graph.halo();
  if (!(seconds_per_mp > 0) || !(target_seconds > 0)) return align_tile(kMaxAutoTile, a);
  // (tile + 2 halo)^2 pixels are computed for a tile.
  const double computed = target_seconds / seconds_per_mp * 1e6;
  const int64_t edge = static_cast<int64_t>(std::sqrt(computed)) - 2 * halo;
  // Below 8 halos the halo's recomputation would cost over half as much again as the tile (1.25^2).
  return align_tile(std::clamp<int64_t>(edge, std::max<int64_t>(8 * halo, 64), kMaxAutoTile), a);
}

Rect checked_region(const DenoiseOptions& options, int64_t w, int64_t h) {
  const Rect bounds{0, 0, w, h};
  const Rect region = options.roi.value_or(bounds);
  if (region.empty() || !bounds.contains(region))
    throw Error(ErrorKind::Usage, "the region " + region.to_string() + " is not inside the " + std::to_string(w) + "x" +
                                      std::to_string(h) + " image");
  return region;
}

int64_t choose_tile(const DenoiseOptions& options, const nn::Backend& backend, const nn::Graph& graph, size_t budget,
                    int ensemble) {
  const int64_t a = graph.alignment();
  int64_t tile = options.tile;
  if (tile <= 0) {
    tile = tile_for_memory(backend, graph, budget, ensemble);
    if (tile == 0)
      throw Error(ErrorKind::Usage, "--max-memory " + std::to_string(options.max_memory >> 20) +
                                        " MiB is too small even for 16-pixel tiles of this model");
    return tile;
  }
  tile = align_tile(tile, a);
  if (tile_bytes(backend, graph, tile, ensemble) > budget)
    throw Error(ErrorKind::Usage, "tiles of " + std::to_string(tile) + " px need " +
                                      std::to_string(tile_bytes(backend, graph, tile, ensemble) >> 20) +
                                      " MiB, over --max-memory; use smaller tiles or more memory");
  return tile;
}

}  // namespace residue
