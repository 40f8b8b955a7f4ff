// Residue's own models: the direct residual networks (flat and multi-scale). Log features in, log colour out;
// the output guard, the variance blend, the energy correction and the strength around the network. A
// post-correction model (Architecture::prior) refines another method's denoise of the whole image, run first.
#include <algorithm>
#include <cfloat>
#include <memory>

#include "core/denoise/engine/pass_runner.h"
#include "core/denoise/method.h"
#include "core/denoise/method_registry.h"
#include "core/denoise/variance_blend.h"
#include "core/features/features.h"
#include "core/util/error.h"

namespace residue {
namespace {

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

class ResidueMethod final : public Method {
 public:
  explicit ResidueMethod(std::shared_ptr<const nn::Model> model)
      : model_(std::move(model)), prior_(model_->prior ? make_method(model_->prior) : nullptr) {}

  std::string name() const override { return model_->name; }
  std::string architecture() const override { return model_->architecture(); }
  FeatureSet features() const override { return model_->features(); }
  const nn::Model* model() const override { return model_.get(); }
  void check_inputs(const AovStack& stack) const override {
    check_features_available(stack, model_->network.arch.features);
  }
  bool streams() const override { return !prior_; }

  float variance_blend_tau(const DenoiseOptions& o) const override {
    // Not for a post-correction model: where the blend would keep the noisy input, its prior (OIDN) is already
    // cleaner (measured: mean relMSE 0.00311 with the blend, 0.00306 without, on the starter validation scenes).
    if (!o.variance_blend || prior_) return 0.0f;
    return o.blend_tau > 0 ? o.blend_tau : blend_tau(model_->metadata);
  }

  int64_t work(int64_t width, int64_t height, const DenoiseOptions& o) const override {
    const int64_t own = region_pixels(width, height, o) * pass(o).work_per_pixel();
    return own + (prior_ ? prior_->work(width, height, whole_image_options(o)) : 0);
  }

  Image denoise(const AovStack& stack, const DenoiseOptions& o, const TileCallback& on_tile, DenoiseStats& stats,
                WorkCounter& work) const override {
    check_inputs(stack);
    if (!prior_ || stack.prior) return run_pass(stack, pass(o), o, on_tile, stats, work);
    // Post-correction: the prior's denoise of the whole image (the main pass reads it around its region too),
    // then this model with it.
    AovStack with = stack;
    DenoiseStats prior_stats;
    with.prior = Aov{prior_->denoise(stack, whole_image_options(o), preliminary(on_tile), prior_stats, work), {}, {}, 0};
    with.prior->source.layer = prior_->name();
    return run_pass(with, pass(o), o, on_tile, stats, work);
  }

  DenoiseStats denoise_to_exr(const AovReader& reader, const DenoiseOptions& o, const std::filesystem::path& output,
                              io::ExrWriteOptions exr, const TileCallback& on_tile, WorkCounter& work) const override {
    if (prior_)
      throw Error(ErrorKind::Usage, model_->name + " refines " + prior_->name() + "'s denoise of the whole render and so "
                                    "needs it in memory; raise --max-memory");
    check_inputs(reader.layout());
    return stream_pass(reader, pass(o), o, output, std::move(exr), on_tile, work);
  }

 private:
  NetworkPass pass(const DenoiseOptions& o) const {
    const nn::Model& m = *model_;
    const nn::Architecture& arch = m.network.arch;
    NetworkPass p;
    p.model = &m;
    p.skip_empty = o.skip_empty_tiles;
    p.guard = o.output_guard;
    p.energy_correction = o.energy_correction;
    p.blend_tau = variance_blend_tau(o);
    p.strength = o.strength;
    p.ensemble = ensemble_members(o, m);
    p.turned_normal_plane = first_plane(arch.features, AovRole::Normal);  // view-space normals turn with the image
    p.needs_exposure = arch.autoexposure;
    p.needs_depth = true;
    p.make_io = [&m](const WholeImageStats& s) {
      FeatureStats f = s.features;
      f.demodulate = m.network.arch.demodulate;
      f.prior = !m.network.arch.prior.empty();
      f.temporal = m.network.arch.temporal;
      f.exposure = m.network.arch.exposure(s.exposure);  // an autoexposed model scales OIDN's exposure to its key
      return std::make_unique<ResidueIO>(m.network.arch.features, f);
    };
    return p;
  }

  std::shared_ptr<const nn::Model> model_;
  std::unique_ptr<Method> prior_;
};

}  // namespace

std::unique_ptr<Method> make_residue_method(std::shared_ptr<const nn::Model> model) {
  return std::make_unique<ResidueMethod>(std::move(model));
}

}  // namespace residue
