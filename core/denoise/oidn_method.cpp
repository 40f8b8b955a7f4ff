// Open Image Denoise's networks, fed and read as OIDN feeds and reads them (oidn_filter.h), for comparison: no
// post-steps but the strength. In OIDN's final-frame mode (a clean-aux network) the albedo and the normal of the
// whole image are denoised first by their prefilters, each a pass of its own.
#include <memory>

#include "core/denoise/engine/pass_runner.h"
#include "core/denoise/method.h"
#include "core/denoise/method_registry.h"
#include "core/denoise/oidn_filter.h"
#include "core/util/error.h"

namespace residue {
namespace {

class OidnIO final : public NetworkIO {
 public:
  explicit OidnIO(OidnTransform t) : t_(std::move(t)) {}
  void input(const AovStack& src, const Rect& r, Image& planes) const override { t_.input(src, r, planes); }
  float output(float raw, const AovStack&, int64_t, int64_t, int) const override { return t_.output(raw); }

 private:
  OidnTransform t_;
};

class OidnMethod final : public Method {
 public:
  explicit OidnMethod(std::shared_ptr<const nn::Model> model) : model_(std::move(model)) {
    if (model_->albedo_prefilter) albedo_ = std::make_unique<OidnMethod>(model_->albedo_prefilter);
    if (model_->normal_prefilter) normal_ = std::make_unique<OidnMethod>(model_->normal_prefilter);
  }

  std::string name() const override { return model_->name; }
  std::string architecture() const override { return model_->architecture(); }
  FeatureSet features() const override { return model_->features(); }
  const nn::Model* model() const override { return model_.get(); }
  bool streams() const override { return !albedo_ && !normal_; }

  void check_inputs(const AovStack& stack) const override {
    const std::string who = "Open Image Denoise's network " + model_->name;
    if (model_->oidn.albedo && !stack.albedo) throw Error(ErrorKind::Input, who + " needs an albedo AOV; the render has none");
    if (model_->oidn.normal && !stack.normal) throw Error(ErrorKind::Input, who + " needs a normal AOV; the render has none");
  }

  int64_t work(int64_t width, int64_t height, const DenoiseOptions& o) const override {
    int64_t w = region_pixels(width, height, o) * pass(o).work_per_pixel();
    for (const auto* pre : {albedo_.get(), normal_.get()})
      if (pre) w += pre->work(width, height, whole_image_options(o));
    return w;
  }

  Image denoise(const AovStack& stack, const DenoiseOptions& o, const TileCallback& on_tile, DenoiseStats& stats,
                WorkCounter& work) const override {
    check_inputs(stack);
    if (!albedo_ && !normal_) return run_pass(stack, pass(o), o, on_tile, stats, work);
    AovStack clean = stack;
    DenoiseStats pre_stats;
    if (albedo_) clean.albedo->image = albedo_->denoise(stack, whole_image_options(o), preliminary(on_tile), pre_stats, work);
    if (normal_) clean.normal->image = normal_->denoise(stack, whole_image_options(o), preliminary(on_tile), pre_stats, work);
    return run_pass(clean, pass(o), o, on_tile, stats, work);
  }

  DenoiseStats denoise_to_exr(const AovReader& reader, const DenoiseOptions& o, const std::filesystem::path& output,
                              io::ExrWriteOptions exr, const TileCallback& on_tile, WorkCounter& work) const override {
    check_inputs(reader.layout());
    if (!streams())
      throw Error(ErrorKind::Usage, model_->name + " (OIDN's clean-aux mode) denoises the albedo and normal of the whole "
                                    "render first and so needs it in memory; raise --max-memory");
    return stream_pass(reader, pass(o), o, output, std::move(exr), on_tile, work);
  }

 private:
  NetworkPass pass(const DenoiseOptions& o) const {
    const nn::Model& m = *model_;
    NetworkPass p;
    p.model = &m;
    // A prefilter's output is the albedo or normal it cleans.
    p.replaces = m.oidn.color ? AovRole::Color : m.oidn.albedo ? AovRole::Albedo : AovRole::Normal;
    p.strength = o.strength;
    p.ensemble = ensemble_members(o, m);  // OIDN's normals (any space) are flipped with the image, not turned
    p.needs_exposure = m.oidn.color && m.oidn.hdr;
    p.make_io = [&m](const WholeImageStats& s) { return std::make_unique<OidnIO>(OidnTransform(m.oidn, s.exposure)); };
    return p;
  }

  std::shared_ptr<const nn::Model> model_;
  std::unique_ptr<OidnMethod> albedo_, normal_;
};

}  // namespace

std::unique_ptr<Method> make_oidn_method(std::shared_ptr<const nn::Model> model) {
  return std::make_unique<OidnMethod>(std::move(model));
}

}  // namespace residue
