#include "core/denoise/engine/pass_runner.h"

#include <algorithm>
#include <cstring>
#include <memory>
#include <string>

#include "core/denoise/engine/band_denoiser.h"
#include "core/denoise/engine/row_source.h"
#include "core/denoise/engine/tiling.h"
#include "core/denoise/provenance_of.h"
#include "core/util/error.h"

namespace residue {
namespace {

std::string backend_for(const DenoiseOptions& o) {
  return o.backend.empty() ? nn::default_backend(o.precision) : o.backend;
}

// The options' cached backend for `model`, or a fresh one held by `owned`.
nn::Backend& backend_of(const DenoiseOptions& o, const nn::Model& model, std::unique_ptr<nn::Backend>& owned) {
  if (o.backends) return o.backends->get(model, backend_for(o), o.precision);
  owned = nn::make_backend(backend_for(o), model.graph, {o.precision});
  return *owned;
}

}  // namespace

Image run_pass(const AovStack& stack, const NetworkPass& pass, const DenoiseOptions& options,
               const TileCallback& on_tile, DenoiseStats& stats, WorkCounter& work) {
  const Image& source = stack.find(pass.replaces)->image;
  if (const NonFiniteCount bad = count_non_finite(source);
      source.size() > 0 && bad.total() == static_cast<int64_t>(source.size()))
    throw Error(ErrorKind::Input, "'" + stack.color.source.file + "': the " +
                                      (pass.replaces == AovRole::Color ? std::string("colour") : std::string("auxiliary")) +
                                      " to denoise has no finite value (" + std::to_string(bad.nan) + " NaN, " +
                                      std::to_string(bad.inf) + " Inf)");
  const Rect region = checked_region(options, stack.width(), stack.height());
  std::unique_ptr<nn::Backend> owned;
  nn::Backend& backend = backend_of(options, *pass.model, owned);
  const nn::Graph& graph = pass.model->graph;
  // The output is held whole: the tiles get the rest of the budget.
  const size_t output_bytes = source.size() * sizeof(float);
  const size_t budget = options.max_memory > output_bytes ? options.max_memory - output_bytes : 0;
  int64_t tile = choose_tile(options, backend, graph, budget, pass.ensemble);
  const int64_t a = graph.alignment();
  if (options.tile <= 0) tile = std::min(tile, (std::max(region.width, region.height) + a - 1) / a * a);

  StackRows rows(stack);
  BandDenoiser engine(rows, pass, options, backend, tile, on_tile, stats, work);
  Image output(stack.width(), stack.height(), source.channels());
  for (int64_t y0 = 0; y0 < stack.height(); y0 += tile) {
    const int64_t n = std::min(tile, stack.height() - y0);
    const Image band = engine.band(y0, n);
    std::memcpy(&output.at(0, y0, 0), band.data(), band.size() * sizeof(float));
  }
  return output;
}

DenoiseStats stream_pass(const AovReader& reader, const NetworkPass& pass, const DenoiseOptions& options,
                         const std::filesystem::path& output, io::ExrWriteOptions exr, const TileCallback& on_tile,
                         WorkCounter& work) {
  const AovStack& layout = reader.layout();
  const int64_t W = layout.data_window.width, H = layout.data_window.height;
  const int64_t stack_channels = layout.channel_count();  // floats per pixel of a band as read
  DenoiseStats stats;
  std::unique_ptr<nn::Backend> owned;
  nn::Backend& backend = backend_of(options, *pass.model, owned);
  const nn::Graph& graph = pass.model->graph;
  const int64_t h = graph.halo(), a = graph.alignment();
  const bool correct = pass.energy_correction;
  const size_t correction_grid =
      correct ? static_cast<size_t>((W / EnergyCorrection::kBlock + 1) * (H / EnergyCorrection::kBlock + 1)) *
                    EnergyCorrection::kBytesPerBlock
              : 0;
  // Memory of one band of tile rows: its input rows with halos (and the two halos kept for the next band), its
  // output rows (and those denoised ahead), and one tile's work.
  auto band_bytes = [&](int64_t tile) {
    return static_cast<size_t>(((tile + 4 * h) * stack_channels + (1 + BandDenoiser::bands_ahead(correct, tile)) * tile * 3) * W) *
               sizeof(float) +
           tile_bytes(backend, graph, tile, pass.ensemble) + correction_grid;
  };
  int64_t tile = options.tile > 0 ? align_tile(options.tile, a) : 0;
  if (tile <= 0)
    for (int64_t t = kMaxAutoTile; t >= 16 && tile <= 0; t = t * 3 / 4)
      if (band_bytes(align_tile(t, a)) <= options.max_memory) tile = align_tile(t, a);
  if (tile <= 0 || band_bytes(tile) > options.max_memory)
    throw Error(ErrorKind::Usage, "--max-memory " + std::to_string(options.max_memory >> 20) + " MiB cannot hold a band of " +
                                      std::to_string(std::max<int64_t>(tile, 16)) + "-pixel tiles of this " +
                                      std::to_string(W) + "-pixel-wide image");
  ReaderRows rows(reader, 2 * h);
  BandDenoiser engine(rows, pass, options, backend, tile, on_tile, stats, work);
  io::record(exr.residue_attributes, run_provenance(stats));  // the header is written first: no time yet
  stats.clamped_to_half =
      io::write_exr_bands(output, W, H, 3, tile, exr, [&](int64_t y0, int64_t n) { return engine.band(y0, n); })
          .clamped_to_half;
  return stats;
}

}  // namespace residue
