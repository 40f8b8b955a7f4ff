// Cutting a denoise into tiles: their grid, their halos and their size within a memory budget.
//
// Tiles lie on the image's grid (from its origin) so that each starts on the network's alignment grid and the
// network's pooling grid is the image's: tiled output equals untiled. Each tile is extended by a halo equal to
// the network's receptive field and only its centre is kept.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/image/image.h"
#include "core/nn/backend.h"
#include "core/nn/graph.h"

namespace residue {

struct DenoiseOptions;

// Largest tile edge tried when none is given: big tiles waste less on halos, but progress comes per tile.
inline constexpr int64_t kMaxAutoTile = 1024;

// Tile rectangles covering `region`, row by row.
std::vector<Rect> make_tiles(const Rect& region, int64_t tile);

// Tiles of `tile` px on the grid of `bounds` (from its origin), cut to `region`.
std::vector<Rect> grid_tiles(const Rect& bounds, const Rect& region, int64_t tile);

// The tile with its halo, clipped to `bounds`, its origin moved down to the graph's alignment grid.
Rect expand(const Rect& r, int64_t halo, const Rect& bounds, int64_t align);

// A tile edge rounded down to the network's alignment (at least one alignment).
int64_t align_tile(int64_t tile, int64_t align);

// Bytes one tile of edge `tile` takes: the backend's scratch and the tile's planes (features, padded features,
// output; a self-ensemble adds the turned input and output and the output turned back).
size_t tile_bytes(const nn::Backend& backend, const nn::Graph& graph, int64_t tile, int ensemble);

// The tile edge (a multiple of the graph's alignment) that keeps one tile's memory within `budget` bytes, or 0
// when even 16 px does not fit.
int64_t tile_for_memory(const nn::Backend& backend, const nn::Graph& graph, size_t budget, int ensemble = 1);

// The tile edge for interactive use (the viewer): tiles that take about `target_seconds` each at
// `seconds_per_mp` (the model's measured speed, halo included in the work), so that progress shows often and
// one layer of a tile (where a oneDNN run can be cancelled) is over well within a second; but never below 8
// halos (the recomputed halo then costs at most 56 % more than the tile itself) nor above 1024 px.
int64_t interactive_tile(const nn::Graph& graph, double seconds_per_mp, double target_seconds = 0.5);

// The region a denoise covers (the options' ROI, else the image); Error(Usage) when it is not inside.
Rect checked_region(const DenoiseOptions& options, int64_t width, int64_t height);

// The tile edge of an in-memory denoise: the option (rounded down to the alignment), or the largest within
// `budget`; Error(Usage) naming --max-memory when it does not fit.
int64_t choose_tile(const DenoiseOptions& options, const nn::Backend& backend, const nn::Graph& graph, size_t budget,
                    int ensemble);

}  // namespace residue
