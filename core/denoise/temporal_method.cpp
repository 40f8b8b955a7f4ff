// Residue's temporal networks (issue 51): a frame of a shot denoised with its neighbours' noisy colour warped
// to it (AovStack::neighbours, attached by core/temporal/frame_window.h before the denoise). The network is a
// Residue network with 4 more input planes per neighbour, run as residue_method runs one; what this method adds
// is what a shot needs: the frames it reads each side, no streaming (the neighbours are whole images in memory),
// and no variance blend (a frame's variance knows nothing of the neighbours' samples it averaged in).
#include <memory>

#include "core/denoise/method.h"
#include "core/denoise/method_registry.h"
#include "core/util/error.h"

namespace residue {
namespace {

class TemporalMethod final : public Method {
 public:
  explicit TemporalMethod(std::shared_ptr<const nn::Model> model)
      : radius_(model->network.arch.temporal), network_(make_residue_method(std::move(model))) {
    if (radius_ < 1) throw Error(ErrorKind::Usage, network_->name() + " reads no neighbouring frames: not a temporal model");
  }

  std::string name() const override { return network_->name(); }
  std::string architecture() const override { return network_->architecture(); }
  FeatureSet features() const override { return network_->features(); }
  const nn::Model* model() const override { return network_->model(); }
  int frame_radius() const override { return radius_; }
  // A frame without neighbours (a still, a shot's ends) is denoised from what it has: every neighbour's planes
  // read as not valid, as a disoccluded pixel's do.
  void check_inputs(const AovStack& stack) const override { network_->check_inputs(stack); }
  int64_t work(int64_t width, int64_t height, const DenoiseOptions& o) const override {
    return network_->work(width, height, without_blend(o));
  }
  Image denoise(const AovStack& stack, const DenoiseOptions& o, const TileCallback& on_tile, DenoiseStats& stats,
                WorkCounter& work) const override {
    return network_->denoise(stack, without_blend(o), on_tile, stats, work);
  }

 private:
  static DenoiseOptions without_blend(DenoiseOptions o) {
    o.variance_blend = false;
    return o;
  }

  int radius_;
  std::unique_ptr<Method> network_;
};

}  // namespace

std::unique_ptr<Method> make_temporal_method(std::shared_ptr<const nn::Model> model) {
  return std::make_unique<TemporalMethod>(std::move(model));
}

}  // namespace residue
