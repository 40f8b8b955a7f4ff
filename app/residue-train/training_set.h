// Training data: scenes laid out like ../shared/datasets/cycles-starter (s<seed>/noisy_a.exr, noisy_b.exr,
// reference.exr), turned into the network's feature planes by core's loader and feature code (the same code
// inference uses), and sampled as augmented 64x64 patches that prefer noisy, non-flat regions.
#pragma once

#include <filesystem>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <torch/torch.h>

#include "core/aov/aov_stack.h"
#include "core/features/feature_set.h"
#include "core/image/image.h"
#include "core/nn/model_file.h"
#include "core/nn/network.h"
#include "core/nn/safetensors.h"

namespace residue::train {

struct TrainingScene {
  std::string name;
  std::vector<Image> inputs;   // feature planes of each noisy half, H x W x C
  std::vector<Image> targets;  // each half's target: log(1 + reference x the half's exposure), H x W x 3
  std::vector<float> exposures;  // each half's exposure (1 without autoexposure)
  Image noise;  // per pixel: the colour's relative noise from the two halves, which the patch weights average
  // Patch sampling: top-left corners on a grid and their probabilities.
  std::vector<std::pair<int64_t, int64_t>> corners;
  std::vector<double> weights;
  int previous = -1;  // a shot's frame: the index of the frame before it among the set's scenes; -1 none
};

// Distillation: each half's target is moved towards what a teacher model makes of that half, (1 - weight) x
// log(1 + reference) + weight x log(1 + the teacher's output), both at the half's exposure. The teacher runs once
// per half by core's denoiser as `-m` runs it (post-steps on), under `ensemble` flips: a self-ensemble of the model
// being fine-tuned is a smoother function of the same input than the single network, which the student may learn.
struct Teacher {
  const nn::Model* model = nullptr;
  float weight = 0.5f;
  int ensemble = 8;
};

// What one training scene is read from: a data set's scene folder (s<seed>/noisy_a.exr, ...), or one frame of a
// shot (core/aov/shot_dataset.h) with its neighbours warped to it, for a temporal model.
struct TrainingSource {
  TrainingSource(std::filesystem::path scene, std::optional<int> shot_frame = std::nullopt)  // NOLINT: a scene is a source
      : dir(std::move(scene)), frame(shot_frame) {}
  std::filesystem::path dir;
  std::optional<int> frame;  // a shot's frame number; none: a still scene
  std::string name() const;  // "s1010", "s8007/0005"
};
std::vector<TrainingSource> scene_sources(const std::vector<std::filesystem::path>& scenes);
// Every frame of the shots (those with a reference), in order.
std::vector<TrainingSource> shot_sources(const std::vector<std::filesystem::path>& shots);
// The source's stack as inference sees it, with the reference: a scene's noisy_a (load_dataset_scene), or a
// shot's frame with `radius` neighbours each side (load_shot_frame).
AovStack load_source(const TrainingSource& source, int radius);

class TrainingSet {
 public:
  // The input planes of `arch` (its feature set, demodulated or not, with its prior's output: `prior`, run once
  // per noisy half by core's denoiser, as inference runs it); targets from the reference, or distilled (`teacher`).
  TrainingSet(const std::vector<TrainingSource>& scenes, const nn::Architecture& arch, int patch,
              const nn::Model* prior = nullptr, const Teacher& teacher = {});

  // A batch: inputs B x C x P x P, targets B x 3 x P x P. Patches from random scenes, corners drawn by
  // the noise weights, one of the 8 flips/rotations applied (normals turned with the image).
  void sample(std::mt19937& rng, int batch, torch::Tensor& inputs, torch::Tensor& targets) const;

  // For a temporal loss: `pairs` patches of frame t in the first half of the batch and the same patches (corner and
  // flip) of frame t - 1 of the same shot in the second, inputs 2 pairs x C x P x P. Error(Usage) without frame pairs.
  void sample_pairs(std::mt19937& rng, int pairs, torch::Tensor& inputs, torch::Tensor& targets) const;
  bool has_pairs() const { return !paired_.empty(); }

  size_t size() const { return scenes_.size(); }
  const std::vector<TrainingScene>& scenes() const { return scenes_; }
  int channels() const { return channels_; }

 private:
  // One patch of scene `s` at `corner` under `transform` into batch slot b.
  void copy_patch(const TrainingScene& s, size_t half, std::pair<int64_t, int64_t> corner, int transform, int b,
                  float* in, float* tg) const;

  std::vector<TrainingScene> scenes_;
  std::vector<size_t> paired_;  // scenes with a previous frame
  FeatureSet features_;
  int channels_;
  int patch_;
};

// The loaded scenes as tensors, for a trainer outside this program (tools/models/torch_train.py, on a GPU): per scene i,
// "<prefix>/<i>/input<h>" (H x W x C feature planes of noisy half h), "<prefix>/<i>/target<h>" (H x W x 3, the
// half's target) and "<prefix>/<i>/exposure<h>" (1); for patch sampling, "<prefix>/<i>/corners" (N x 2: x, y) and
// "<prefix>/<i>/weights" (N) of this set's patch size, and "<prefix>/<i>/noise" (H x W x 1), the map they average,
// for any other size. The scene names go in the metadata as "<prefix>.scenes" (a JSON list). Exactly what this
// trainer trains on.
void add_to_export(const TrainingSet& set, const std::string& prefix, nn::SafetensorsFile& out);

// Index of the view-space normal's x plane in a feature set (y follows); -1 when it has none.
int normal_plane(FeatureSet set);
// Index of the albedo's r plane (log(1 + a); g, b follow); -1 when it has none.
int albedo_plane(FeatureSet set);

}  // namespace residue::train
