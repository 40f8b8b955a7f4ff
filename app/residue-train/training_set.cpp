#include "training_set.h"

#include <algorithm>
#include <cstdio>
#include <optional>

#include <nlohmann/json.hpp>

#include "core/aov/aov_loader.h"
#include "core/aov/dataset.h"
#include "core/aov/shot_dataset.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/oidn_filter.h"
#include "core/features/features.h"
#include "core/image/dihedral.h"
#include "core/util/error.h"

namespace residue::train {
namespace fs = std::filesystem;

int normal_plane(FeatureSet set) { return first_plane(set, AovRole::Normal); }
int albedo_plane(FeatureSet set) { return first_plane(set, AovRole::Albedo); }

namespace {

// Per-pixel relative noise of the colour from the two halves: sum over RGB of (a - b)^2 / (r^2 + 0.01).
Image noise_map(const AovStack& a, const AovStack* b, const Image& reference) {
  Image n(a.width(), a.height(), 1, 1.0f);
  if (!b) return n;
  for (int64_t y = 0; y < n.height(); ++y)
    for (int64_t x = 0; x < n.width(); ++x) {
      float s = 0;
      for (int c = 0; c < 3; ++c) {
        const float d = a.color.image.at(x, y, c) - b->color.image.at(x, y, c);
        const float r = reference.at(x, y, c);
        if (std::isfinite(d) && std::isfinite(r)) s += d * d / (r * r + 0.01f);
      }
      n.at(x, y) = std::min(s, 100.0f);
    }
  return n;
}

// A single render's relative error against its reference, where there is no second half to compare with.
Image error_map(const AovStack& a, const Image& reference) {
  Image n(a.width(), a.height(), 1, 1.0f);
  for (int64_t y = 0; y < n.height(); ++y)
    for (int64_t x = 0; x < n.width(); ++x) {
      float s = 0;
      for (int c = 0; c < 3; ++c) {
        const float d = a.color.image.at(x, y, c) - reference.at(x, y, c);
        const float r = reference.at(x, y, c);
        if (std::isfinite(d) && std::isfinite(r)) s += d * d / (r * r + 0.01f);
      }
      n.at(x, y) = std::min(s, 100.0f);
    }
  return n;
}

}  // namespace

std::string TrainingSource::name() const {
  if (!frame) return dir.filename().string();
  char f[16];
  std::snprintf(f, sizeof f, "/%04d", *frame);
  return dir.filename().string() + f;
}

std::vector<TrainingSource> scene_sources(const std::vector<fs::path>& scenes) {
  std::vector<TrainingSource> s;
  for (const auto& d : scenes) s.push_back({d, std::nullopt});
  return s;
}

std::vector<TrainingSource> shot_sources(const std::vector<fs::path>& shots) {
  std::vector<TrainingSource> s;
  for (const auto& d : shots)
    for (int f : shot_frame_numbers(d)) s.push_back({d, f});
  return s;
}

AovStack load_source(const TrainingSource& source, int radius) {
  return source.frame ? load_shot_frame(source.dir, *source.frame, radius) : load_dataset_scene(source.dir);
}

TrainingSet::TrainingSet(const std::vector<TrainingSource>& scenes, const nn::Architecture& arch, int patch,
                         const nn::Model* prior, const Teacher& teacher)
    : features_(arch.features), channels_(arch.in_channels()), patch_(patch) {
  if (!arch.prior.empty() && !prior)
    throw Error(ErrorKind::Usage, "a post-correction network (" + arch.to_string() + ") needs its prior model");
  if (teacher.model && !(teacher.weight > 0 && teacher.weight <= 1))
    throw Error(ErrorKind::Usage, "the teacher's weight must be in (0, 1], not " + std::to_string(teacher.weight));
  const FeatureSet features = arch.features;
  // The stats of each half, with the model's encoding; a post-correction model's prior computed here.
  auto stats = [&](AovStack& s) {
    FeatureStats f = compute_feature_stats(s);
    f.demodulate = arch.demodulate;
    f.prior = !arch.prior.empty();
    f.temporal = arch.temporal;
    f.exposure = arch.autoexposure ? arch.exposure(oidn_autoexposure(s.color.image)) : 1.0f;
    if (f.prior) s.prior = Aov{denoise(s, *prior, {}), {}, {}, 0};
    return f;
  };
  for (const TrainingSource& source : scenes) {
    const fs::path& dir = source.dir;
    AovStack a = load_source(source, arch.temporal);  // with the variance from the two halves when there are two
    if (a.width() < patch || a.height() < patch)
      throw Error(ErrorKind::Input, "scene '" + dir.string() + "' is smaller than one " + std::to_string(patch) + " px patch");
    TrainingScene s;
    s.name = source.name();
    const Rect all{0, 0, a.width(), a.height()};
    // Each half with its target: log(1 + reference), times the half's own exposure for an autoexposed model (the
    // halves' noise gives them slightly different exposures; inference scales by the noisy input's, too).
    auto add_input = [&](AovStack& half) {
      std::optional<Image> taught;  // before stats(), which may give the half a prior's output
      if (teacher.model) {
        DenoiseOptions d;
        d.ensemble = teacher.ensemble;
        d.skip_empty_tiles = false;
        taught = denoise(half, *teacher.model, d);
      }
      const FeatureStats fs = stats(half);
      Image f, target(a.width(), a.height(), 3);
      make_features(half, features, fs, all, f);
      const float w = taught ? teacher.weight : 0.0f;
      for (int64_t y = 0; y < a.height(); ++y)
        for (int64_t x = 0; x < a.width(); ++x)
          for (int c = 0; c < 3; ++c) {
            float t = compress_color(exposed(a.reference->image.at(x, y, c), fs.exposure));
            if (taught) t = (1 - w) * t + w * compress_color(exposed(taught->at(x, y, c), fs.exposure));
            target.at(x, y, c) = t;
          }
      s.exposures.push_back(fs.exposure);
      s.inputs.push_back(std::move(f));
      s.targets.push_back(std::move(target));
    };
    add_input(a);
    std::optional<AovStack> b;
    if (!source.frame && fs::exists(dir / "noisy_b.exr")) {
      LoadOptions lb;
      lb.load_reference = false;
      b = load_aov_stack({dir / "noisy_b.exr"}, lb);
      b->variance = a.variance;  // (a - b)^2 / 2 is the estimate for either half
      add_input(*b);
    }

    // Patch weights: mean relative noise inside the patch, plus a floor so flat regions still appear.
    s.noise = source.frame ? error_map(a, a.reference->image) : noise_map(a, b ? &*b : nullptr, a.reference->image);
    const Image& noise = s.noise;
    Image integral(a.width() + 1, a.height() + 1, 1);  // summed-area table
    for (int64_t y = 0; y < a.height(); ++y)
      for (int64_t x = 0; x < a.width(); ++x)
        integral.at(x + 1, y + 1) = noise.at(x, y) + integral.at(x, y + 1) + integral.at(x + 1, y) - integral.at(x, y);
    const int64_t step = 8;
    double total = 0;
    for (int64_t y = 0; y + patch <= a.height(); y += step)
      for (int64_t x = 0; x + patch <= a.width(); x += step) {
        const double sum = integral.at(x + patch, y + patch) - integral.at(x, y + patch) - integral.at(x + patch, y) +
                           integral.at(x, y);
        s.corners.emplace_back(x, y);
        s.weights.push_back(sum / (patch * patch));
        total += s.weights.back();
      }
    const double floor = 0.25 * total / static_cast<double>(s.weights.size()) + 1e-6;
    for (double& w : s.weights) w += floor;
    if (source.frame && !scenes_.empty() && source.frame > 1) {
      const TrainingSource& prev = scenes[scenes_.size() - 1];
      if (prev.dir == dir && prev.frame == *source.frame - 1) s.previous = static_cast<int>(scenes_.size() - 1);
    }
    if (s.previous >= 0) paired_.push_back(scenes_.size());
    scenes_.push_back(std::move(s));
  }
  if (scenes_.empty()) throw Error(ErrorKind::Input, "no training scenes");
}

void TrainingSet::sample(std::mt19937& rng, int batch, torch::Tensor& inputs, torch::Tensor& targets) const {
  const int64_t P = patch_;
  inputs = torch::empty({batch, channels_, P, P}, torch::kFloat32);
  targets = torch::empty({batch, 3, P, P}, torch::kFloat32);
  float* in = inputs.data_ptr<float>();
  float* tg = targets.data_ptr<float>();
  std::uniform_int_distribution<size_t> pick_scene(0, scenes_.size() - 1);
  std::uniform_int_distribution<int> pick_transform(0, 7);
  for (int b = 0; b < batch; ++b) {
    const TrainingScene& s = scenes_[pick_scene(rng)];
    std::discrete_distribution<size_t> pick_corner(s.weights.begin(), s.weights.end());
    const auto corner = s.corners[pick_corner(rng)];
    const size_t half = std::uniform_int_distribution<size_t>(0, s.inputs.size() - 1)(rng);
    copy_patch(s, half, corner, pick_transform(rng), b, in, tg);
  }
}

void TrainingSet::sample_pairs(std::mt19937& rng, int pairs, torch::Tensor& inputs, torch::Tensor& targets) const {
  if (paired_.empty()) throw Error(ErrorKind::Usage, "a temporal loss needs consecutive frames of shots (--shots)");
  const int64_t P = patch_;
  inputs = torch::empty({2 * pairs, channels_, P, P}, torch::kFloat32);
  targets = torch::empty({2 * pairs, 3, P, P}, torch::kFloat32);
  float* in = inputs.data_ptr<float>();
  float* tg = targets.data_ptr<float>();
  std::uniform_int_distribution<size_t> pick_scene(0, paired_.size() - 1);
  std::uniform_int_distribution<int> pick_transform(0, 7);
  for (int b = 0; b < pairs; ++b) {
    const TrainingScene& s = scenes_[paired_[pick_scene(rng)]];
    std::discrete_distribution<size_t> pick_corner(s.weights.begin(), s.weights.end());
    const auto corner = s.corners[pick_corner(rng)];
    const int transform = pick_transform(rng);
    copy_patch(s, 0, corner, transform, b, in, tg);
    copy_patch(scenes_[static_cast<size_t>(s.previous)], 0, corner, transform, pairs + b, in, tg);
  }
}

void TrainingSet::copy_patch(const TrainingScene& s, size_t half, std::pair<int64_t, int64_t> corner, int transform,
                             int b, float* in, float* tg) const {
  const int64_t P = patch_;
  const int np = normal_plane(features_);
  const auto [x0, y0] = corner;
  {  // NOLINT: the patch's pixels
    const Image& src = s.inputs[half];
    const Image& target = s.targets[half];
    const Dihedral d = Dihedral::from_index(transform);
    for (int64_t v = 0; v < P; ++v)
      for (int64_t u = 0; u < P; ++u) {
        const auto [sx, sy] = d.source(u, v, P, P);
        const int64_t px = x0 + sx, py = y0 + sy;
        for (int c = 0; c < channels_; ++c)
          in[((static_cast<int64_t>(b) * channels_ + c) * P + v) * P + u] = src.at(px, py, c);
        for (int c = 0; c < 3; ++c) tg[((static_cast<int64_t>(b) * 3 + c) * P + v) * P + u] = target.at(px, py, c);
        if (np >= 0) {
          // The normals turn with the image.
          const auto [nx, ny] = d.turn_normal(src.at(px, py, np), src.at(px, py, np + 1));
          in[((static_cast<int64_t>(b) * channels_ + np) * P + v) * P + u] = nx;
          in[((static_cast<int64_t>(b) * channels_ + np + 1) * P + v) * P + u] = ny;
        }
      }
  }
}

void add_to_export(const TrainingSet& set, const std::string& prefix, nn::SafetensorsFile& out) {
  auto image_tensor = [](const Image& im) {
    nn::Tensor t;
    t.shape = {im.height(), im.width(), im.channels()};
    t.values.assign(im.data(), im.data() + im.size());
    return t;
  };
  nlohmann::json names = nlohmann::json::array();
  for (size_t i = 0; i < set.scenes().size(); ++i) {
    const TrainingScene& s = set.scenes()[i];
    const std::string key = prefix + "/" + std::to_string(i) + "/";
    names.push_back(s.name);
    for (size_t h = 0; h < s.inputs.size(); ++h) {
      out.tensors[key + "input" + std::to_string(h)] = image_tensor(s.inputs[h]);
      out.tensors[key + "target" + std::to_string(h)] = image_tensor(s.targets[h]);
      out.tensors[key + "exposure" + std::to_string(h)] = nn::Tensor{"F32", {1}, {s.exposures[h]}};
    }
    nn::Tensor corners, weights;
    corners.shape = {static_cast<int64_t>(s.corners.size()), 2};
    for (const auto& [x, y] : s.corners) {
      corners.values.push_back(static_cast<float>(x));
      corners.values.push_back(static_cast<float>(y));
    }
    weights.shape = {static_cast<int64_t>(s.weights.size())};
    weights.values.assign(s.weights.begin(), s.weights.end());
    out.tensors[key + "noise"] = image_tensor(s.noise);
    out.tensors[key + "corners"] = std::move(corners);
    out.tensors[key + "weights"] = std::move(weights);
  }
  out.metadata[prefix + ".scenes"] = names.dump();
}

}  // namespace residue::train
