#include "core/features/features.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <vector>

#include <tbb/parallel_for.h>

#include "core/util/error.h"

namespace residue {
namespace {

float sanitize_nonnegative(float v) { return std::isfinite(v) && v > 0.0f ? v : 0.0f; }

}  // namespace

float compress_color(float linear) { return std::log1p(sanitize_nonnegative(linear)); }

float expand_color(float y) {
  if (!(y > 0.0f)) return 0.0f;  // negatives and NaN
  constexpr float kMaxLog = 88.72f;  // log(FLT_MAX) - a little: expm1 stays finite
  return std::min(std::expm1(std::min(y, kMaxLog)), FLT_MAX);
}

float demodulation_factor(float albedo) { return sanitize_nonnegative(albedo) + 0.01f; }

float exposed(float linear, float exposure) {
  const float v = linear * exposure;
  return std::isinf(v) && std::isfinite(linear) ? FLT_MAX : v;
}

DepthScaleSampler::DepthScaleSampler(int64_t pixel_count)
    : stride_(std::max<int64_t>(1, pixel_count / (int64_t{1} << 20))) {}

void DepthScaleSampler::add(const float* depth, int64_t count, int64_t first) {
  for (int64_t i = (stride_ - first % stride_) % stride_; i < count; i += stride_) samples_.push_back(depth[i]);
}

double DepthScaleSampler::scale() {
  // The median of the hits, rounded to 1/8 octave: robust to outliers, and one odd pixel almost never moves
  // it, so bad pixels stay local (their receptive field).
  std::erase_if(samples_, [](float v) { return !(std::isfinite(v) && v > 0); });
  if (samples_.empty()) return 1.0;
  auto mid = samples_.begin() + static_cast<std::ptrdiff_t>(samples_.size() / 2);
  std::nth_element(samples_.begin(), mid, samples_.end());
  return std::exp2(std::round(std::log2(static_cast<double>(*mid)) * 8.0) / 8.0);
}

FeatureStats compute_feature_stats(const AovStack& stack) {
  FeatureStats s;
  if (stack.depth) {
    const Image& d = stack.depth->image;
    DepthScaleSampler sampler(d.pixel_count());
    sampler.add(d.data(), d.pixel_count(), 0);
    s.depth_scale = sampler.scale();
  }
  if (stack.normal && stack.normal_space == NormalSpace::World && stack.world_to_camera) {
    s.rotate_normals = true;
    const auto& m = *stack.world_to_camera;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) s.normal_rotation[static_cast<size_t>(r * 3 + c)] = m[static_cast<size_t>(r * 4 + c)];
  }
  return s;
}

FeatureSet feature_set_for(const AovStack& stack) {
  if (stack.albedo && stack.normal && stack.depth && stack.variance) return FeatureSet::FullVariance;
  if (stack.albedo && stack.normal && stack.depth) return FeatureSet::Full;
  if (stack.albedo && stack.normal) return FeatureSet::ColorAlbedoNormal;
  return FeatureSet::ColorOnly;
}

void check_features_available(const AovStack& stack, FeatureSet set) {
  std::string missing;
  auto need = [&](bool present, const char* name) {
    if (!present) missing += (missing.empty() ? "" : ", ") + std::string(name);
  };
  if (set != FeatureSet::ColorOnly) {
    need(stack.albedo.has_value(), "albedo");
    need(stack.normal.has_value(), "normal");
  }
  if (set == FeatureSet::Full || set == FeatureSet::FullVariance) need(stack.depth.has_value(), "depth");
  if (set == FeatureSet::FullVariance) need(stack.variance.has_value(), "variance");
  if (!missing.empty())
    throw Error(ErrorKind::Input, "the model reads the \"" + std::string(to_string(set)) + "\" feature set but '" +
                                      stack.color.source.file + "' has no " + missing +
                                      " AOV; use a model for \"" + to_string(feature_set_for(stack)) + "\"");
}

void make_features(const AovStack& stack, FeatureSet set, const FeatureStats& stats, const Rect& rect, Image& out) {
  check_features_available(stack, set);
  if (stats.demodulate && !stack.albedo)
    throw Error(ErrorKind::Input, "a demodulated model needs an albedo AOV; '" + stack.color.source.file + "' has none");
  if (stats.prior && (!stack.prior || set != FeatureSet::Full))
    throw Error(ErrorKind::Usage, "a post-correction model reads the full AOV set and its prior model's output; "
                                  "the prior was not computed or the set is not \"full\"");
  const int channels = feature_channels(set) + (stats.prior ? 3 : 0) + 8 * stats.temporal;
  std::vector<const WarpedNeighbour*> neighbours;  // null: missing, read as this frame's colour, not valid
  for (int d : neighbour_offsets(stats.temporal)) {
    const WarpedNeighbour* n = stack.neighbour(d);
    if (n && (n->color.width() != stack.width() || n->color.height() != stack.height() || n->color.channels() != 3 ||
              n->valid.width() != stack.width() || n->valid.height() != stack.height() || n->valid.channels() != 1))
      throw Error(ErrorKind::Usage, "the neighbour at offset " + std::to_string(d) + " of '" + stack.color.source.file +
                                    "' is not 3 + 1 channels on the frame's grid");
    neighbours.push_back(n);
  }
  if (out.width() != rect.width || out.height() != rect.height || out.channels() != channels)
    out = Image(rect.width, rect.height, channels);
  const float inv_depth_mean = static_cast<float>(1.0 / stats.depth_scale);
  const float e = stats.exposure;
  const auto& r = stats.normal_rotation;
  tbb::parallel_for(int64_t{0}, rect.height, [&](int64_t y) {
    const int64_t sy = rect.y + y;
    for (int64_t x = 0; x < rect.width; ++x) {
      const int64_t sx = rect.x + x;
      float* f = &out.at(x, y, 0);
      if (stats.demodulate) {
        for (int c = 0; c < 3; ++c)
          *f++ = compress_color(exposed(stack.color.image.at(sx, sy, c), e) / demodulation_factor(stack.albedo->image.at(sx, sy, c)));
      } else {
        for (int c = 0; c < 3; ++c) *f++ = compress_color(exposed(stack.color.image.at(sx, sy, c), e));
      }
      if (set == FeatureSet::ColorOnly) continue;
      const bool depth = set == FeatureSet::Full || set == FeatureSet::FullVariance;
      if (depth) *f++ = std::log1p(sanitize_nonnegative(stack.depth->image.at(sx, sy)) * inv_depth_mean);
      double n[3];
      for (int c = 0; c < 3; ++c) {
        const float v = stack.normal->image.at(sx, sy, c);
        n[c] = std::isfinite(v) ? v : 0.0;
      }
      if (stats.rotate_normals) {
        const double nx = r[0] * n[0] + r[1] * n[1] + r[2] * n[2];
        const double ny = r[3] * n[0] + r[4] * n[1] + r[5] * n[2];
        n[0] = nx;
        n[1] = ny;
      }
      *f++ = static_cast<float>(std::clamp(n[0], -1.0, 1.0));
      *f++ = static_cast<float>(std::clamp(n[1], -1.0, 1.0));
      for (int c = 0; c < 3; ++c) *f++ = compress_color(stack.albedo->image.at(sx, sy, c));
      if (set == FeatureSet::FullVariance) {
        const Image& var = stack.variance->image;
        const int nv = std::min(3, var.channels());
        double sum = 0;
        for (int c = 0; c < nv; ++c) sum += sanitize_nonnegative(var.at(sx, sy, c));
        *f++ = static_cast<float>(std::log1p(std::sqrt(sum / nv) * e));  // a standard deviation: scales as colour
      }
      if (stats.prior)
        for (int c = 0; c < 3; ++c) {
          const float p = exposed(stack.prior->image.at(sx, sy, c), e);
          *f++ = compress_color(stats.demodulate ? p / demodulation_factor(stack.albedo->image.at(sx, sy, c)) : p);
        }
      for (const WarpedNeighbour* nb : neighbours) {
        const bool valid = nb && nb->valid.at(sx, sy) > 0.5f;
        const Image& from = valid ? nb->color : stack.color.image;
        for (int c = 0; c < 3; ++c) *f++ = compress_color(exposed(from.at(sx, sy, c), e));
        *f++ = valid ? 1.0f : 0.0f;
      }
    }
  });
}


}  // namespace residue
