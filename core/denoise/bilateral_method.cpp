// The cross-bilateral filter (bilateral.h) as a method: no model and no network. It runs tile by tile over the
// region, so that it reports progress and stops on a cancel like the networks do.
#include <algorithm>
#include <memory>

#include "core/denoise/bilateral.h"
#include "core/denoise/engine/tiling.h"
#include "core/denoise/method.h"
#include "core/denoise/method_registry.h"
#include "core/denoise/strength.h"
#include "core/features/features.h"

namespace residue {
namespace {

class BilateralMethod final : public Method {
 public:
  // Tiles of this edge: a 1024x1024 image's filter reports about 64 times.
  static constexpr int64_t kTile = 128;
  // Work units of one tap of the filter (one neighbour's weight and colour), against a network's FLOPs.
  static constexpr int64_t kWorkPerTap = 24;

  std::string name() const override { return "bilateral"; }
  std::string architecture() const override { return "cross-bilateral filter"; }
  FeatureSet features() const override { return FeatureSet::Full; }  // the guides it has; none needed
  void check_inputs(const AovStack&) const override {}

  int64_t work(int64_t width, int64_t height, const DenoiseOptions& o) const override {
    return region_pixels(width, height, o) * work_per_pixel();
  }

  Image denoise(const AovStack& stack, const DenoiseOptions& o, const TileCallback& on_tile, DenoiseStats& stats,
                WorkCounter& work) const override {
    const Rect region = checked_region(o, stack.width(), stack.height());
    const std::vector<Rect> tiles = make_tiles(region, kTile);
    Image out = stack.color.image;
    int64_t done = 0;
    for (const Rect& t : tiles) {
      throw_if_cancelled(o.cancel);
      cross_bilateral_rect(stack, options_, t, out);
      work.done += t.area() * work_per_pixel();
      ++done;
      if (on_tile && !on_tile({t, false, done, static_cast<int64_t>(tiles.size()), work.done, work.total, true}, crop(out, t)))
        throw Cancelled();
    }
    stats.tiles = static_cast<int64_t>(tiles.size());
    stats.tile_size = kTile;
    stats.backend = "cross-bilateral (core)";
    stats.features = feature_set_for(stack);
    stats.strength = o.strength;
    return with_strength(stack.color.image, out, o.strength);
  }

 private:
  int64_t work_per_pixel() const { return (2 * options_.radius + 1) * (2 * options_.radius + 1) * kWorkPerTap; }

  BilateralOptions options_;
};

}  // namespace

std::unique_ptr<Method> make_bilateral_method(std::shared_ptr<const nn::Model>) {
  return std::make_unique<BilateralMethod>();
}

}  // namespace residue
