#include "core/denoise/denoiser.h"

#include <algorithm>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <cstring>
#include <deque>

#include <tbb/task_arena.h>

#include "core/denoise/energy_correction.h"
#include "core/denoise/oidn_filter.h"
#include "core/denoise/output_guard.h"
#include "core/denoise/strength.h"
#include "core/denoise/variance_blend.h"
#include "core/features/features.h"
#include "core/image/dihedral.h"
#include "core/io/exr_writer.h"
#include "core/io/provenance.h"
#include "core/util/error.h"

namespace residue {
namespace {

// Largest tile edge tried when none is given: big tiles waste less on halos, but progress comes per tile.
constexpr int64_t kMaxAutoTile = 1024;

size_t tile_bytes(const nn::Backend& backend, const nn::Graph& graph, int64_t tile, int ensemble) {
  const int64_t a = graph.alignment();
  const int64_t e = (tile + 2 * graph.halo() + a - 1) / a * a;
  const size_t pixels = static_cast<size_t>(e * e);
  // Features, padded features and the output; a self-ensemble adds the turned input and output and the output
  // turned back.
  const int64_t planes = 2 * graph.input_channels() + graph.output_channels() +
                         (ensemble > 1 ? graph.input_channels() + 2 * graph.output_channels() : 0);
  return backend.scratch_bytes(e, e) + pixels * static_cast<size_t>(planes) * sizeof(float);
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

// The tile with its halo, clipped to `bounds`, its origin moved down to the graph's alignment grid (so that the
// network's pooling grid is the image's, and tiled output equals untiled).
Rect expand(const Rect& r, int64_t halo, const Rect& bounds, int64_t align) {
  const int64_t x0 = std::max(bounds.x, r.x - halo) / align * align, y0 = std::max(bounds.y, r.y - halo) / align * align;
  const int64_t x1 = std::min(bounds.x + bounds.width, r.x + r.width + halo);
  const int64_t y1 = std::min(bounds.y + bounds.height, r.y + r.height + halo);
  return {x0, y0, x1 - x0, y1 - y0};
}

}  // namespace

float variance_blend_tau(const DenoiseOptions& o, const nn::Model& model) {
  // Not for a post-correction model: where the blend would keep the noisy input, its prior (OIDN) is already
  // cleaner (measured: mean relMSE 0.00311 with the blend, 0.00306 without, on the starter validation scenes).
  if (!o.variance_blend || model.method != nn::Method::Residue || !model.network.arch.prior.empty()) return 0.0f;
  return o.blend_tau > 0 ? o.blend_tau : blend_tau(model.metadata);
}

namespace {

// The self-ensemble's size for this denoise: the option, else the model's (residue.ensemble), else 1.
int ensemble_for(const DenoiseOptions& o, const nn::Model& model) {
  const int n = o.ensemble > 0 ? o.ensemble : model.ensemble;
  if (n != 1 && n != 2 && n != 4 && n != 8)
    throw Error(ErrorKind::Usage, "the self-ensemble has 1, 2, 4 or 8 members (flips and transposes), not " + std::to_string(n));
  return n;
}

// The input plane the self-ensemble turns as a view-space normal (x, then y): Residue's models'; OIDN's normals
// (any space, as OIDN takes them) are flipped with the image but not turned.
int turned_normal_plane(const nn::Model& model) {
  return model.method == nn::Method::Residue ? feature_plane(model.network.arch.features, "normal.x") : -1;
}

// How a model's network is fed and read: AOVs -> input planes, raw output -> linear values.
class NetworkIO {
 public:
  virtual ~NetworkIO() = default;
  // The input planes of rectangle r of `src` (its pixel coordinates).
  virtual void input(const AovStack& src, const Rect& r, Image& planes) const = 0;
  // The linear value of raw output `raw` at pixel (x, y), channel c of `src`.
  virtual float output(float raw, const AovStack& src, int64_t x, int64_t y, int c) const = 0;
};

// Residue's models: log features (core/features), log colour out.
class ResidueIO final : public NetworkIO {
 public:
  ResidueIO(FeatureSet set, FeatureStats stats) : set_(set), stats_(stats) {}
  void input(const AovStack& src, const Rect& r, Image& planes) const override {
    make_features(src, set_, stats_, r, planes);
  }
  float output(float raw, const AovStack& src, int64_t x, int64_t y, int c) const override {
    float v = expand_color(raw);
    if (stats_.demodulate) v = std::min(v * demodulation_factor(src.albedo->image.at(x, y, c)), FLT_MAX);
    return std::min(v / stats_.exposure, FLT_MAX);  // exposure 1 (every other model): v unchanged
  }

 private:
  FeatureSet set_;
  FeatureStats stats_;
};

// Open Image Denoise's networks, fed and read as OIDN does (oidn_filter.h).
class OidnIO final : public NetworkIO {
 public:
  explicit OidnIO(OidnTransform t) : t_(std::move(t)) {}
  void input(const AovStack& src, const Rect& r, Image& planes) const override { t_.input(src, r, planes); }
  float output(float raw, const AovStack&, int64_t, int64_t, int) const override { return t_.output(raw); }

 private:
  OidnTransform t_;
};

using residue_io_t = std::unique_ptr<NetworkIO>;

// The image a model's output replaces: the colour, or for an OIDN prefilter the albedo or normal it cleans.
const Image& source_image(const AovStack& stack, const nn::Model& model) {
  if (model.method == nn::Method::Oidn && !model.oidn.color)
    return model.oidn.albedo ? stack.albedo->image : stack.normal->image;
  return stack.color.image;
}

void check_inputs(const AovStack& stack, const nn::Model& model) {
  if (model.method == nn::Method::Residue) return check_features_available(stack, model.network.arch.features);
  const std::string who = "Open Image Denoise's network " + model.name;
  if (model.oidn.albedo && !stack.albedo) throw Error(ErrorKind::Input, who + " needs an albedo AOV; the render has none");
  if (model.oidn.normal && !stack.normal) throw Error(ErrorKind::Input, who + " needs a normal AOV; the render has none");
}

// Denoises one tile. `src` holds the image's pixels of `src_rect` (image coordinates; it covers the tile and
// its halo); the result goes to `out` at the tile's position minus (out_x0, out_y0). Returns true when skipped.
struct TileRunner {
  const nn::Model& model;
  nn::Backend& backend;
  const NetworkIO& io;
  bool skip_empty;
  bool guard;       // clamp overshoots to the receptive field's brightest input (output_guard.h)
  float blend_tau;  // variance blend (when the stack has variance); 0: off
  const CancelToken* cancel;
  int ensemble = 1;       // dihedral elements averaged (denoiser.h, DenoiseOptions::ensemble)
  int normal_plane = -1;  // the input plane of the view-space normal's x (turned with the image), or -1
  int64_t guarded = 0;    // values the guard clamped so far
  Image features, padded, result, turned_in, turned_out;

  bool run(const AovStack& src, const Rect& src_rect, const Rect& bounds, const Rect& t, Image& out, int64_t out_x0,
           int64_t out_y0) {
    throw_if_cancelled(cancel);
    const nn::Graph& g = model.graph;
    const int64_t halo = g.halo(), align = g.alignment();
    const bool residue = model.method == nn::Method::Residue;
    Rect in = expand(t, halo, bounds, align);
    in.x -= src_rect.x;
    in.y -= src_rect.y;
    const int64_t tx = t.x - src_rect.x, ty = t.y - src_rect.y;
    const int oc = out.channels();
    if (residue && skip_empty && colour_is_empty(src.color.image, in)) {
      for (int64_t y = t.y; y < t.y + t.height; ++y)
        std::memset(&out.at(t.x - out_x0, y - out_y0, 0), 0, static_cast<size_t>(t.width * oc) * sizeof(float));
      return true;
    }
    io.input(src, in, features);
    // Networks that pool take tiles of whole multiples of their alignment: zeros past the image's edge, as
    // when the whole image is padded.
    const Image* net_in = &features;
    if (in.width % align != 0 || in.height % align != 0) {
      padded = Image((in.width + align - 1) / align * align, (in.height + align - 1) / align * align, features.channels());
      for (int64_t y = 0; y < in.height; ++y)
        std::memcpy(&padded.at(0, y, 0), features.row(y).data(), static_cast<size_t>(in.width * features.channels()) * sizeof(float));
      net_in = &padded;
    }
    const Rect core{tx - in.x, ty - in.y, t.width, t.height};  // the tile in the network's input, without its halo
    // The self-ensemble: the network on the tile under each flip (and transpose), each output turned back; the
    // mean of their linear values. Member 0 is the tile as it is.
    int64_t non_finite = 0;
    const float weight = 1.0f / static_cast<float>(ensemble);
    for (int k = 0; k < ensemble; ++k) {
      if (k == 0) {
        backend.run(*net_in, result, cancel, core);
      } else {
        const Dihedral d = Dihedral::from_index(k);
        turned_in = apply(*net_in, d, normal_plane);
        backend.run(turned_in, turned_out, cancel, d.map(core, net_in->width(), net_in->height()));
        result = apply(turned_out, d.inverse());
      }
      if (residue && guard) guarded += guard_output(features, core, halo, result);
      for (int64_t y = 0; y < t.height; ++y)
        for (int64_t x = 0; x < t.width; ++x)
          for (int c = 0; c < oc; ++c) {
            const float raw = result.at(core.x + x, core.y + y, c);
            non_finite += !std::isfinite(raw);
            const float v = io.output(raw, src, tx + x, ty + y, c);
            float& o = out.at(t.x - out_x0 + x, t.y - out_y0 + y, c);
            o = (k == 0 ? 0.0f : o) + weight * v;  // one member: weight 1, v itself
          }
    }
    // Output is finite or the run fails: a network whose weights or inputs overflow does not get written as a
    // black or saturated image with success (the output transforms would turn NaN into 0 and Inf into FLT_MAX).
    if (non_finite > 0)
      throw Error(ErrorKind::Input, "model " + model.name + " gave " + std::to_string(non_finite) +
                                        " non-finite output values in the tile " + t.to_string() +
                                        " (its weights or the render's values overflow fp32); nothing was written");
    if (blend_tau > 0 && src.variance) blend_by_variance(src, src_rect, bounds, t, out, out_x0, out_y0, blend_tau);
    return false;
  }
};

// Tiles of `tile` px on the image's grid (from its origin, so that each starts on the alignment grid), cut to
// `region`.
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

}  // namespace

nn::Backend& BackendCache::get(const nn::Model& model, const std::string& backend, nn::Precision precision) {
  auto& slot = backends_[{&model, backend, precision}];
  if (!slot) slot = nn::make_backend(backend, model.graph, {precision});
  return *slot;
}

std::vector<Rect> make_tiles(const Rect& region, int64_t tile) {
  std::vector<Rect> tiles;
  for (int64_t y = region.y; y < region.y + region.height; y += tile)
    for (int64_t x = region.x; x < region.x + region.width; x += tile)
      tiles.push_back({x, y, std::min(tile, region.x + region.width - x), std::min(tile, region.y + region.height - y)});
  return tiles;
}

namespace {

// A tile edge rounded down to the network's alignment (at least one alignment).
int64_t align_tile(int64_t tile, int64_t align) { return std::max(align, tile / align * align); }

}  // namespace

int64_t interactive_tile(const nn::Graph& graph, double seconds_per_mp, double target_seconds) {
  const int64_t a = graph.alignment(), halo = graph.halo();
  if (!(seconds_per_mp > 0) || !(target_seconds > 0)) return align_tile(kMaxAutoTile, a);
  // (tile + 2 halo)^2 pixels are computed for a tile.
  const double computed = target_seconds / seconds_per_mp * 1e6;
  const int64_t edge = static_cast<int64_t>(std::sqrt(computed)) - 2 * halo;
  // Below 8 halos the halo's recomputation would cost over half as much again as the tile (1.25^2).
  return align_tile(std::clamp<int64_t>(edge, std::max<int64_t>(8 * halo, 64), kMaxAutoTile), a);
}

int64_t tile_for_memory(const nn::Backend& backend, const nn::Graph& graph, size_t budget, int ensemble) {
  for (int64_t t = kMaxAutoTile; t >= 16; t = t * 3 / 4) {
    const int64_t aligned = align_tile(t, graph.alignment());
    if (tile_bytes(backend, graph, aligned, ensemble) <= budget) return aligned;
  }
  return 0;
}

namespace {

Rect checked_region(const DenoiseOptions& options, int64_t w, int64_t h) {
  const Rect bounds{0, 0, w, h};
  const Rect region = options.roi.value_or(bounds);
  if (region.empty() || !bounds.contains(region))
    throw Error(ErrorKind::Usage, "the region " + region.to_string() + " is not inside the " + std::to_string(w) + "x" +
                                      std::to_string(h) + " image");
  return region;
}

// The tile edge: the option (rounded down to the network's alignment), or the largest within `budget`.
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

std::string backend_for(const DenoiseOptions& o) {
  return o.backend.empty() ? nn::default_backend(o.precision) : o.backend;
}

// The options' cached backend for `model`, or a fresh one held by `owned`.
nn::Backend& backend_of(const DenoiseOptions& o, const nn::Model& model, std::unique_ptr<nn::Backend>& owned) {
  if (o.backends) return o.backends->get(model, backend_for(o), o.precision);
  owned = nn::make_backend(backend_for(o), model.graph, {o.precision});
  return *owned;
}

// Where the rows of a denoise come from: a stack in memory (every row at hand, no copy), or the render's files
// read band by band (AovReader). rows() gives a stack and the rectangle of the image it holds; `roles` limits
// what a source that reads must read (empty: every AOV the denoise uses).
class RowSource {
 public:
  virtual ~RowSource() = default;
  virtual const AovStack& layout() const = 0;
  virtual const AovStack* whole() const { return nullptr; }  // in memory: the statistics come from it directly
  struct Rows {
    AovStack owned;  // read from the files (unused in memory)
    const AovStack* stack = nullptr;
    Rect rect;
  };
  virtual Rows rows(int64_t y0, int64_t y1, const std::vector<AovRole>& roles = {}) = 0;
};

class StackRows final : public RowSource {
 public:
  explicit StackRows(const AovStack& stack) : stack_(stack) {}
  const AovStack& layout() const override { return stack_; }
  const AovStack* whole() const override { return &stack_; }
  Rows rows(int64_t, int64_t, const std::vector<AovRole>&) override {
    return {{}, &stack_, {0, 0, stack_.width(), stack_.height()}};
  }

 private:
  const AovStack& stack_;
};

// Reads each row once: consecutive bands overlap by their halos, and the rows a band shares with the one before
// are taken from it instead of the files. The reference is never read (the denoise does not use it).
class ReaderRows final : public RowSource {
 public:
  // `keep`: rows at the bottom of a band that the next one shares (two halos).
  ReaderRows(const AovReader& reader, int64_t keep) : reader_(reader), keep_(keep) {
    for (AovRole r : {AovRole::Color, AovRole::Albedo, AovRole::Normal, AovRole::Depth, AovRole::Variance})
      if (reader.layout().find(r)) used_.push_back(r);
  }
  const AovStack& layout() const override { return reader_.layout(); }
  Rows rows(int64_t y0, int64_t y1, const std::vector<AovRole>& roles) override {
    const int64_t W = layout().data_window.width;
    Rows r;
    r.rect = {0, y0, W, y1 - y0};
    const bool all = roles.empty();
    const int64_t c0 = last_.y, c1 = last_.y + last_.height;
    if (all && !last_.empty() && c0 <= y0 && y0 < c1 && c1 < y1) {
      // The shared rows from the last band, the rest from the files.
      r.owned = reader_.read({0, c1, W, y1 - c1}, used_);
      for (AovRole role : used_) {
        const Image& prev = cached_.find(role)->image;
        Image& next = r.owned.find(role)->image;
        Image joined(W, y1 - y0, next.channels());
        const size_t row = static_cast<size_t>(W * next.channels());
        std::memcpy(joined.data(), prev.row(y0 - c0).data(), static_cast<size_t>(c1 - y0) * row * sizeof(float));
        std::memcpy(joined.row(c1 - y0).data(), next.data(), next.size() * sizeof(float));
        next = std::move(joined);
      }
    } else {
      r.owned = reader_.read(r.rect, all ? used_ : roles);
    }
    if (all) {  // the bottom rows, for the next band
      const int64_t k = std::min(keep_, y1 - y0);
      last_ = {0, y1 - k, W, k};
      cached_ = AovStack();
      for (AovRole role : used_) cached_.emplace(role).image = crop(r.owned.find(role)->image, {0, y1 - k - y0, W, k});
    }
    r.stack = &r.owned;
    return r;
  }

 private:
  const AovReader& reader_;
  int64_t keep_;
  std::vector<AovRole> used_;
  AovStack cached_;  // the bottom rows of the last band
  Rect last_{};
};

// `exposure`: OIDN's autoexposure of the image, which an autoexposed model scales to its key.
FeatureStats with_encoding(FeatureStats stats, const nn::Model& model, float exposure) {
  stats.demodulate = model.network.arch.demodulate;
  stats.prior = !model.network.arch.prior.empty();
  stats.exposure = model.network.arch.exposure(exposure);
  return stats;
}

// The whole-image statistics a model's input needs, before any tile runs: the depth scale (Residue's models),
// the autoexposure (OIDN's HDR networks, Residue's autoexposed ones); from the stack in memory, or from one pass
// over the files' bands.
residue_io_t network_io(RowSource& source, const nn::Model& model, int64_t band, const CancelToken* cancel) {
  const bool residue = model.method == nn::Method::Residue;
  const bool exposure = residue ? model.network.arch.autoexposure : model.oidn.color && model.oidn.hdr;
  if (const AovStack* stack = source.whole()) {
    const float scale = exposure ? oidn_autoexposure(stack->color.image) : 1.0f;
    return residue ? residue_io_t(std::make_unique<ResidueIO>(model.network.arch.features,
                                                              with_encoding(compute_feature_stats(*stack), model, scale)))
                   : residue_io_t(std::make_unique<OidnIO>(OidnTransform(model.oidn, scale)));
  }
  const AovStack& layout = source.layout();
  const int64_t W = layout.data_window.width, H = layout.data_window.height;
  FeatureStats fstats = compute_feature_stats(layout);
  const bool depth = residue && layout.depth;
  OidnAutoexposure autoexposure(W, H);
  if (depth || exposure) {
    const int64_t stride = depth_sample_stride(W * H);
    std::vector<float> samples;  // the same sample compute_feature_stats draws from a whole stack
    std::vector<AovRole> roles;  // only what the statistics read
    if (exposure) roles.push_back(AovRole::Color);
    if (depth) roles.push_back(AovRole::Depth);
    for (int64_t y0 = 0; y0 < H; y0 += band) {
      throw_if_cancelled(cancel);
      const auto rows = source.rows(y0, std::min(H, y0 + band), roles);
      if (exposure) autoexposure.add(rows.stack->color.image, y0);
      if (!depth) continue;
      for (int64_t i = 0; i < rows.stack->depth->image.pixel_count(); ++i)
        if ((y0 * W + i) % stride == 0) samples.push_back(rows.stack->depth->image.data()[i]);
    }
    if (depth) fstats.depth_scale = depth_scale_from_samples(samples);
  }
  const float scale = exposure ? autoexposure.scale() : 1.0f;
  return residue ? residue_io_t(std::make_unique<ResidueIO>(model.network.arch.features, with_encoding(fstats, model, scale)))
                 : residue_io_t(std::make_unique<OidnIO>(OidnTransform(model.oidn, scale)));
}

// The tile engine: one denoise, planned once, produced band by band (a band is one row of tiles) in order, each
// band through the same stages: features -> network (+ output guard) -> variance blend, per tile; then the
// energy correction (which needs the rows a few blocks below: bands are denoised that far ahead) and the
// strength blend. The sink pulls bands: an image in memory, or a streamed EXR.
class BandDenoiser {
 public:
  BandDenoiser(RowSource& source, const nn::Model& model, const DenoiseOptions& options, nn::Backend& backend,
               int64_t tile, const TileCallback& on_tile, DenoiseStats& stats)
      : source_(source), model_(model), options_(options), on_tile_(on_tile), stats_(stats), tile_(tile),
        W_(source.layout().data_window.width), H_(source.layout().data_window.height),
        region_(checked_region(options, W_, H_)),
        io_(network_io(source, model, tile, options.cancel)),
        tiles_(grid_tiles({0, 0, W_, H_}, region_, tile)),
        runner_{model, backend, *io_, options.skip_empty_tiles, options.output_guard, variance_blend_tau(options, model),
                options.cancel, ensemble_for(options, model), turned_normal_plane(model)},
        correct_(correcting(options, model)), correction_(region_) {
    stats_.tiles = static_cast<int64_t>(tiles_.size());
    stats_.tile_size = tile;
    stats_.ensemble = runner_.ensemble;
    stats_.backend = backend.description();
    stats_.features = model.features();
    stats_.energy_corrected = correct_;
    stats_.variance_blended = runner_.blend_tau > 0 && source.layout().variance.has_value();
  }

  static bool correcting(const DenoiseOptions& o, const nn::Model& m) {
    return o.energy_correction && m.method == nn::Method::Residue;
  }
  // Bands the energy correction needs denoised ahead of the one it finishes.
  static int64_t bands_ahead(bool correct, int64_t tile) {
    return correct ? (EnergyCorrection::kBlock * (EnergyCorrection::kRadiusBlocks + 2) + tile - 1) / tile : 0;
  }

  // Rows [y0, y0 + rows) finished, for y0 on the band grid, in order.
  Image band(int64_t y0, int64_t rows) {
    const int64_t needed = correct_ ? std::max(y0 + rows, correction_.rows_required(y0 + rows)) : y0 + rows;
    while (denoised_end_ < needed) denoise_band(denoised_end_);
    Band b = std::move(denoised_.front());
    denoised_.pop_front();
    if (correct_) correction_.apply(b.out, b.y0, y0, rows);
    if (b.blend) apply_strength(b.base, b.y0, b.out, b.y0, region_, y0, rows, options_.strength);
    stats_.guarded_values = runner_.guarded;
    check_finite(b.out, y0, rows);
    return std::move(b.out);
  }

 private:
  struct Band {
    int64_t y0;
    Image out;
    Image base;  // the band's noisy colour, for the strength blend
    bool blend = false;
  };

  // Output is finite or the run fails, after every post-step too. Only the region is the model's: outside it the
  // input stays as it was, NaN included.
  void check_finite(const Image& out, int64_t y0, int64_t rows) const {
    int64_t bad = 0;
    const int64_t first = std::max(y0, region_.y), end = std::min(y0 + rows, region_.y + region_.height);
    for (int64_t y = first; y < end; ++y)
      for (int64_t x = region_.x; x < region_.x + region_.width; ++x)
        for (int c = 0; c < out.channels(); ++c) bad += !std::isfinite(out.at(x, y - y0, c));
    if (bad > 0)
      throw Error(ErrorKind::Input, model_.name + ": " + std::to_string(bad) + " output values of rows " +
                                        std::to_string(first) + "-" + std::to_string(end - 1) +
                                        " are not finite after the post-steps; nothing was written");
  }

  void denoise_band(int64_t y0) {
    const int64_t rows = std::min(tile_, H_ - y0), h = model_.graph.halo();
    const int64_t in_y0 = std::max<int64_t>(0, y0 - h), in_y1 = std::min(H_, y0 + rows + h);
    const RowSource::Rows in = source_.rows(in_y0, in_y1);
    const Image& base = source_image(*in.stack, model_);  // outside the region the input stays
    Band b{y0, crop(base, {0, y0 - in.rect.y, W_, rows}), {}, false};
    // The strength blends back towards the noisy colour; an OIDN prefilter's albedo or normal is kept whole.
    b.blend = options_.strength < 1.0f && &base == &in.stack->color.image;
    if (b.blend) b.base = b.out;
    stats_.strength = &base == &in.stack->color.image ? options_.strength : 1.0f;
    for (const Rect& t : tiles_) {
      if (t.y < y0 || t.y >= y0 + rows) continue;
      const bool skip = runner_.run(*in.stack, in.rect, {0, 0, W_, H_}, t, b.out, 0, y0);
      if (skip) ++stats_.skipped;
      ++done_;
      if (on_tile_ && !on_tile_({t, skip, done_, stats_.tiles}, crop(b.out, {t.x, t.y - y0, t.width, t.height})))
        throw Cancelled();
    }
    if (correct_) correction_.accumulate(in.stack->color.image, in.rect.y, b.out, y0, y0, rows);
    denoised_.push_back(std::move(b));
    denoised_end_ = y0 + rows;
  }

  RowSource& source_;
  const nn::Model& model_;
  const DenoiseOptions& options_;
  const TileCallback& on_tile_;
  DenoiseStats& stats_;
  int64_t tile_, W_, H_;
  Rect region_;
  residue_io_t io_;
  std::vector<Rect> tiles_;
  TileRunner runner_;
  bool correct_;
  EnergyCorrection correction_;
  std::deque<Band> denoised_;  // bands denoised but not handed out yet
  int64_t denoised_end_ = 0;   // rows denoised so far
  int64_t done_ = 0;           // tiles
};

// The whole denoise of a stack in memory with one model (an OIDN prefilter included: its output is the image it
// cleans, albedo or normal).
Image denoise_stack(const AovStack& stack, const nn::Model& model, const DenoiseOptions& options,
                    const TileCallback& on_tile, DenoiseStats& local) {
  check_inputs(stack, model);
  const Image& source = source_image(stack, model);
  if (const NonFiniteCount bad = count_non_finite(source);
      source.size() > 0 && bad.total() == static_cast<int64_t>(source.size()))
    throw Error(ErrorKind::Input, "'" + stack.color.source.file + "': the " +
                                      (&source == &stack.color.image ? std::string("colour") : std::string("auxiliary")) +
                                      " to denoise has no finite value (" + std::to_string(bad.nan) + " NaN, " +
                                      std::to_string(bad.inf) + " Inf)");
  const Rect region = checked_region(options, stack.width(), stack.height());
  std::unique_ptr<nn::Backend> owned;
  nn::Backend& backend = backend_of(options, model, owned);
  // The output is held whole: the tiles get the rest of the budget.
  const size_t output_bytes = source.size() * sizeof(float);
  const size_t budget = options.max_memory > output_bytes ? options.max_memory - output_bytes : 0;
  int64_t tile = choose_tile(options, backend, model.graph, budget, ensemble_for(options, model));
  const int64_t a = model.graph.alignment();
  if (options.tile <= 0) tile = std::min(tile, (std::max(region.width, region.height) + a - 1) / a * a);

  StackRows rows(stack);
  BandDenoiser engine(rows, model, options, backend, tile, on_tile, local);
  Image output(stack.width(), stack.height(), source.channels());
  for (int64_t y0 = 0; y0 < stack.height(); y0 += tile) {
    const int64_t n = std::min(tile, stack.height() - y0);
    const Image band = engine.band(y0, n);
    std::memcpy(&output.at(0, y0, 0), band.data(), band.size() * sizeof(float));
  }
  return output;
}

}  // namespace

Image denoise(const AovStack& stack, const nn::Model& model, const DenoiseOptions& options, const TileCallback& on_tile,
              DenoiseStats* stats) {
  const auto start = std::chrono::steady_clock::now();
  check_strength(options.strength);
  const int threads = options.threads > 0 ? options.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  DenoiseStats local;
  Image output;
  arena.execute([&] {
    // A network that runs before this one, on the whole image (the main pass reads its output around its region
    // too), at full strength.
    auto whole_image = [&](const nn::Model& first) {
      DenoiseOptions whole = options;
      whole.roi.reset();
      whole.strength = 1.0f;
      whole.ensemble = 1;  // a prior or prefilter runs as it was trained with
      DenoiseStats ignored;
      return denoise(stack, first, whole, {}, &ignored);
    };
    if (model.prior && !stack.prior) {
      // Post-correction: the prior model's denoise, then this model with it.
      AovStack with = stack;
      with.prior = Aov{whole_image(*model.prior), {}, {}, 0};
      with.prior->source.layer = model.prior->name;
      output = denoise_stack(with, model, options, on_tile, local);
    } else if (model.albedo_prefilter || model.normal_prefilter) {
      // OIDN's final-frame mode: albedo and normal denoised first, then the colour with them.
      check_inputs(stack, model);
      AovStack clean = stack;
      if (model.albedo_prefilter) clean.albedo->image = whole_image(*model.albedo_prefilter);
      if (model.normal_prefilter) clean.normal->image = whole_image(*model.normal_prefilter);
      output = denoise_stack(clean, model, options, on_tile, local);
    } else {
      output = denoise_stack(stack, model, options, on_tile, local);
    }
  });
  local.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (stats) *stats = local;
  return output;
}

DenoiseStats denoise_to_exr(const AovReader& reader, const nn::Model& model, const DenoiseOptions& options,
                            const std::filesystem::path& output, io::ExrWriteOptions exr, const TileCallback& on_tile) {
  const auto start = std::chrono::steady_clock::now();
  check_strength(options.strength);
  const AovStack& layout = reader.layout();
  check_inputs(layout, model);
  if (model.albedo_prefilter || model.normal_prefilter)
    throw Error(ErrorKind::Usage, model.name + " (OIDN's clean-aux mode) denoises the albedo and normal of the whole "
                                  "render first and so needs it in memory; raise --max-memory");
  if (model.prior)
    throw Error(ErrorKind::Usage, model.name + " refines " + model.prior->name + "'s denoise of the whole render and so "
                                  "needs it in memory; raise --max-memory");
  const int64_t W = layout.data_window.width, H = layout.data_window.height;
  checked_region(options, W, H);  // before any work
  const int64_t stack_channels = layout.channel_count();  // floats per pixel of a band as read

  if (exr.data_window.empty()) exr.data_window = layout.data_window;
  if (exr.display_width <= 0) exr.display_width = layout.display_width;
  if (exr.display_height <= 0) exr.display_height = layout.display_height;
  if (exr.metadata.empty()) exr.metadata = layout.metadata;
  const int threads = options.threads > 0 ? options.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  DenoiseStats local;
  arena.execute([&] {
    std::unique_ptr<nn::Backend> owned;
    nn::Backend& backend = backend_of(options, model, owned);
    const nn::Graph& graph = model.graph;
    const int64_t h = graph.halo(), a = graph.alignment();
    const bool correct = BandDenoiser::correcting(options, model);
    const size_t correction_grid = correct
                                       ? static_cast<size_t>((W / EnergyCorrection::kBlock + 1) * (H / EnergyCorrection::kBlock + 1)) *
                                             EnergyCorrection::kBytesPerBlock
                                       : 0;
    // Memory of one band of tile rows: its input rows with halos (and the two halos kept for the next band), its
    // output rows (and those denoised ahead), and one tile's work.
    auto band_bytes = [&](int64_t tile) {
      return static_cast<size_t>(((tile + 4 * h) * stack_channels + (1 + BandDenoiser::bands_ahead(correct, tile)) * tile * 3) * W) *
                 sizeof(float) +
             tile_bytes(backend, graph, tile, ensemble_for(options, model)) + correction_grid;
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
    BandDenoiser engine(rows, model, options, backend, tile, on_tile, local);
    io::record(exr.residue_attributes, {.backend = local.backend,
                                        .energy_correction = local.energy_corrected,
                                        .variance_blend = local.variance_blended,
                                        .strength = options.strength,
                                        .ensemble = local.ensemble});
    local.clamped_to_half =
        io::write_exr_bands(output, W, H, 3, tile, exr, [&](int64_t y0, int64_t n) { return engine.band(y0, n); })
            .clamped_to_half;
  });
  local.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return local;
}

}  // namespace residue
