#include "core/denoise/engine/band_denoiser.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/denoise/engine/tiling.h"
#include "core/denoise/strength.h"
#include "core/util/error.h"

namespace residue {
namespace {

std::unique_ptr<NetworkIO> measured_io(RowSource& source, const NetworkPass& pass, int64_t band,
                                       const CancelToken* cancel) {
  return pass.make_io(measure_whole_image(source, pass.needs_exposure, pass.needs_depth, band, cancel));
}

}  // namespace

BandDenoiser::BandDenoiser(RowSource& source, const NetworkPass& pass, const DenoiseOptions& options,
                           nn::Backend& backend, int64_t tile, const TileCallback& on_tile, DenoiseStats& stats,
                           WorkCounter& work)
    : source_(source), pass_(pass), options_(options), on_tile_(on_tile), stats_(stats), work_(work), tile_(tile),
      W_(source.layout().data_window.width), H_(source.layout().data_window.height),
      region_(checked_region(options, W_, H_)),
      io_(measured_io(source, pass, tile, options.cancel)),
      tiles_(grid_tiles({0, 0, W_, H_}, region_, tile)),
      runner_(pass, backend, *io_, options.cancel),
      correction_(region_) {
  stats_.tiles = static_cast<int64_t>(tiles_.size());
  stats_.tile_size = tile;
  stats_.ensemble = pass.ensemble;
  stats_.backend = backend.description();
  stats_.features = pass.model->features();
  stats_.energy_corrected = pass.energy_correction;
  stats_.variance_blended = pass.blend_tau > 0 && source.layout().variance.has_value();
  stats_.strength = pass.replaces == AovRole::Color ? pass.strength : 1.0f;  // a prefilter's image is kept whole
}

int64_t BandDenoiser::bands_ahead(bool correct, int64_t tile) {
  return correct ? (EnergyCorrection::kBlock * (EnergyCorrection::kRadiusBlocks + 2) + tile - 1) / tile : 0;
}

Image BandDenoiser::band(int64_t y0, int64_t rows) {
  const bool correct = pass_.energy_correction;
  const int64_t needed = correct ? std::max(y0 + rows, correction_.rows_required(y0 + rows)) : y0 + rows;
  while (denoised_end_ < needed) denoise_band(denoised_end_);
  Band b = std::move(denoised_.front());
  denoised_.pop_front();
  if (correct) correction_.apply(b.out, b.y0, y0, rows);
  if (b.blend) apply_strength(b.base, b.y0, b.out, b.y0, region_, y0, rows, pass_.strength);
  stats_.guarded_values = runner_.guarded();
  check_finite(b.out, y0, rows);
  return std::move(b.out);
}

// Output is finite or the run fails, after every post-step too. Only the region is the model's: outside it the
// input stays as it was, NaN included.
void BandDenoiser::check_finite(const Image& out, int64_t y0, int64_t rows) const {
  int64_t bad = 0;
  const int64_t first = std::max(y0, region_.y), end = std::min(y0 + rows, region_.y + region_.height);
  for (int64_t y = first; y < end; ++y)
    for (int64_t x = region_.x; x < region_.x + region_.width; ++x)
      for (int c = 0; c < out.channels(); ++c) bad += !std::isfinite(out.at(x, y - y0, c));
  if (bad > 0)
    throw Error(ErrorKind::Input, pass_.model->name + ": " + std::to_string(bad) + " output values of rows " +
                                      std::to_string(first) + "-" + std::to_string(end - 1) +
                                      " are not finite after the post-steps; nothing was written");
}

void BandDenoiser::denoise_band(int64_t y0) {
  const int64_t rows = std::min(tile_, H_ - y0), h = pass_.model->graph.halo();
  const int64_t in_y0 = std::max<int64_t>(0, y0 - h), in_y1 = std::min(H_, y0 + rows + h);
  const RowSource::Rows in = source_.rows(in_y0, in_y1);
  const Image& base = in.stack->find(pass_.replaces)->image;  // outside the region the input stays
  Band b{y0, crop(base, {0, y0 - in.rect.y, W_, rows}), {}, false};
  // The strength blends back towards the noisy colour; an OIDN prefilter's albedo or normal is kept whole.
  const bool colour = pass_.replaces == AovRole::Color;
  b.blend = pass_.strength < 1.0f && colour;
  if (b.blend) b.base = b.out;
  const int64_t per_pixel = pass_.work_per_pixel();
  for (const Rect& t : tiles_) {
    if (t.y < y0 || t.y >= y0 + rows) continue;
    const bool skip = runner_.run(*in.stack, in.rect, {0, 0, W_, H_}, t, b.out, 0, y0);
    if (skip) ++stats_.skipped;
    ++done_;
    work_.done += t.area() * per_pixel;
    if (on_tile_ && !on_tile_({t, skip, done_, stats_.tiles, work_.done, work_.total, true},
                              crop(b.out, {t.x, t.y - y0, t.width, t.height})))
      throw Cancelled();
  }
  if (pass_.energy_correction) correction_.accumulate(in.stack->color.image, in.rect.y, b.out, y0, y0, rows);
  denoised_.push_back(std::move(b));
  denoised_end_ = y0 + rows;
}

}  // namespace residue
