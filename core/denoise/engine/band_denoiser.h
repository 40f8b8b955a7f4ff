// The tile engine: one network pass, planned once, produced band by band (a band is one row of tiles) in order,
// each band through the same stages: features -> network (+ output guard) -> variance blend, per tile; then the
// energy correction (which needs the rows a few blocks below: bands are denoised that far ahead) and the
// strength blend. The caller pulls bands: into an image in memory, or into a streamed EXR.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <vector>

#include "core/denoise/denoiser.h"
#include "core/denoise/energy_correction.h"
#include "core/denoise/engine/network_pass.h"
#include "core/denoise/engine/row_source.h"
#include "core/denoise/engine/tile_runner.h"

namespace residue {

class BandDenoiser {
 public:
  BandDenoiser(RowSource& source, const NetworkPass& pass, const DenoiseOptions& options, nn::Backend& backend,
               int64_t tile, const TileCallback& on_tile, DenoiseStats& stats, WorkCounter& work);

  // Bands the energy correction needs denoised ahead of the one it finishes.
  static int64_t bands_ahead(bool correct, int64_t tile);

  // Rows [y0, y0 + rows) finished, for y0 on the band grid, in order.
  Image band(int64_t y0, int64_t rows);

 private:
  struct Band {
    int64_t y0;
    Image out;
    Image base;  // the band's noisy colour, for the strength blend
    bool blend = false;
  };
  void check_finite(const Image& out, int64_t y0, int64_t rows) const;
  void denoise_band(int64_t y0);

  RowSource& source_;
  const NetworkPass& pass_;
  const DenoiseOptions& options_;
  const TileCallback& on_tile_;
  DenoiseStats& stats_;
  WorkCounter& work_;
  int64_t tile_, W_, H_;
  Rect region_;
  std::unique_ptr<NetworkIO> io_;
  std::vector<Rect> tiles_;
  TileRunner runner_;
  EnergyCorrection correction_;
  std::deque<Band> denoised_;  // bands denoised but not handed out yet
  int64_t denoised_end_ = 0;   // rows denoised so far
  int64_t done_ = 0;           // tiles
};

}  // namespace residue
