// The temporal blend (core/temporal/temporal_blend.h): frame t's denoised colour averaged with its neighbours'
// warped denoised colour, against a float64 evaluation of the rule written out here; the mask, the colour
// tolerance (a highlight the motion does not follow is left out), non-finite neighbours, and a pan's frames
// brought to frame t by warp_to_frame and averaged into frame t's own colour where it is the same surface.
#include <cmath>

#include <gtest/gtest.h>

#include "core/temporal/frame_window.h"
#include "core/temporal/temporal_blend.h"
#include "core/util/error.h"
#include "support/test_support.h"

namespace residue {
namespace {

constexpr int64_t kW = 9, kH = 7;

WarpedNeighbour neighbour(int offset, const Image& color, float valid = 1.0f) {
  WarpedNeighbour n{offset, color, Image(color.width(), color.height(), 1)};
  for (size_t i = 0; i < n.valid.size(); ++i) n.valid.data()[i] = valid;
  return n;
}

// The rule, in float64: weight 1 for frame t, 1 - (d / tol)^2 for a valid neighbour with d = sum |b - a| /
// (sum |a| + sum |b| + 1e-3) below tol.
double expected_channel(const Image& a, const std::vector<WarpedNeighbour>& ns, int64_t x, int64_t y, int c, double tol) {
  double sum = a.at(x, y, c), weight = 1;
  for (const auto& n : ns) {
    if (n.valid.at(x, y) < 0.5f) continue;
    double diff = 0, level = 1e-3;
    for (int k = 0; k < 3; ++k) {
      diff += std::abs(double{n.color.at(x, y, k)} - a.at(x, y, k));
      level += std::abs(double{a.at(x, y, k)}) + std::abs(double{n.color.at(x, y, k)});
    }
    const double d = diff / level / tol;
    if (d >= 1) continue;
    sum += (1 - d * d) * n.color.at(x, y, c);
    weight += 1 - d * d;
  }
  return sum / weight;
}

TEST(TemporalBlend, FollowsItsRuleInFloat64) {
  const Image a = testing::random_image(kW, kH, 3, 1, 0.2f, 2.0f);
  Image b = a, c = a;
  // Neighbours close to frame t's colour (a denoiser's flicker), a few far from it (a highlight that moved).
  const Image jitter_b = testing::random_image(kW, kH, 3, 2, -0.15f, 0.15f);
  const Image jitter_c = testing::random_image(kW, kH, 3, 3, -0.15f, 0.15f);
  for (size_t i = 0; i < a.size(); ++i) {
    b.data()[i] = a.data()[i] * (1 + jitter_b.data()[i]);
    c.data()[i] = a.data()[i] * (1 + jitter_c.data()[i]);
  }
  for (int ch = 0; ch < 3; ++ch) b.at(4, 3, ch) = 20.0f;  // a highlight in frame t-1 only
  std::vector<WarpedNeighbour> ns = {neighbour(-1, b), neighbour(1, c)};
  ns[1].valid.at(2, 2) = 0.0f;  // a disocclusion
  const double tol = 0.3;
  const Image out = temporal_blend(a, ns, {.tolerance = tol});
  int blended = 0;
  for (int64_t y = 0; y < kH; ++y)
    for (int64_t x = 0; x < kW; ++x)
      for (int ch = 0; ch < 3; ++ch) {
        EXPECT_NEAR(out.at(x, y, ch), expected_channel(a, ns, x, y, ch, tol), 1e-6 * (1 + std::abs(a.at(x, y, ch))));
        blended += out.at(x, y, ch) != a.at(x, y, ch);
      }
  EXPECT_GT(blended, kW * kH * 3 / 2);  // the rule blends most pixels: this is not the identity
  // The highlight is left out: the pixel is the mean of frames t and t+1 at their weights, nothing of 20.
  EXPECT_LT(out.at(4, 3, 0), 2.5f);
  // A masked neighbour counts for nothing.
  std::vector<WarpedNeighbour> only_prev = {ns[0]};
  const Image prev_only = temporal_blend(a, only_prev, {.tolerance = tol});
  for (int ch = 0; ch < 3; ++ch) EXPECT_FLOAT_EQ(out.at(2, 2, ch), prev_only.at(2, 2, ch));
}

TEST(TemporalBlend, NoNeighbourNaNAndEqualFrames) {
  const Image a = testing::random_image(kW, kH, 3, 4, 0.0f, 1.0f);
  const Image same = temporal_blend(a, {}, {});
  for (size_t i = 0; i < a.size(); ++i) EXPECT_EQ(same.data()[i], a.data()[i]);
  Image b = a;
  b.at(1, 1, 1) = std::nanf("");
  b.at(3, 2, 0) = INFINITY;
  const Image out = temporal_blend(a, {neighbour(-1, b), neighbour(1, a)}, {});
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_TRUE(std::isfinite(out.data()[i]));
    EXPECT_NEAR(out.data()[i], a.data()[i], 1e-6);  // equal frames average to themselves; non-finite ones are left out
  }
  EXPECT_THROW(temporal_blend(a, {neighbour(-1, Image(kW + 1, kH, 3))}, {}), Error);
  EXPECT_THROW(temporal_blend(a, {}, {.tolerance = 0}), Error);
}

// A camera pan of 1 px a frame: frame t-1's image, warped by warp_to_frame, lands on frame t's pixels exactly (the
// motion is an integer), the column the pan brings in is masked, and the blend of three noisy copies of one wall
// has a third of the noise's variance where both neighbours show it.
TEST(TemporalBlend, APanOfNoisyFramesAveragesTheirNoise) {
  constexpr int64_t W = 64, H = 32;
  const Image wall = testing::random_image(W + 4, H, 3, 9, 0.9f, 1.1f);  // the surface, seen through the pan
  std::vector<AovStack> frames;
  std::vector<Image> noisy;
  for (int i = 0; i < 3; ++i) {  // frames t-1, t, t+1: frame i shows the wall from column i
    AovStack s = testing::random_stack(W, H, 20 + i);
    Aov motion;
    motion.image = Image(W, H, 4);
    for (int64_t y = 0; y < H; ++y)
      for (int64_t x = 0; x < W; ++x) {
        s.depth->image.at(x, y) = 3.0f;
        s.normal->image.at(x, y, 0) = 0, s.normal->image.at(x, y, 1) = 0, s.normal->image.at(x, y, 2) = 1;
        motion.image.at(x, y, 0) = -1.0f, motion.image.at(x, y, 2) = 1.0f;  // the surface was 1 px left, will be 1 px right
      }
    s.motion = motion;
    frames.push_back(std::move(s));
    const Image grain = testing::random_image(W, H, 3, 40 + i, -0.05f, 0.05f);
    Image n(W, H, 3);
    for (int64_t y = 0; y < H; ++y)
      for (int64_t x = 0; x < W; ++x)
        for (int c = 0; c < 3; ++c) n.at(x, y, c) = wall.at(x + 2 - i, y, c) + grain.at(x, y, c);
    noisy.push_back(n);
  }
  std::vector<WarpedNeighbour> warped;
  for (int d : {-1, 1}) {
    const ShotFrames shot = [&](int o) -> const AovStack* { return o == d ? &frames[static_cast<size_t>(1 + d)] : nullptr; };
    warped.push_back(*warp_to_frame(frames[1], d, shot, noisy[static_cast<size_t>(1 + d)], noisy[1]));
  }
  // Exact integer warp: frame t-1's pixel x - 1 is frame t's pixel x; the first column has no source.
  EXPECT_EQ(warped[0].valid.at(0, 5), 0.0f);
  EXPECT_EQ(warped[0].color.at(10, 5, 1), noisy[0].at(9, 5, 1));
  EXPECT_EQ(warped[1].valid.at(W - 1, 5), 0.0f);
  EXPECT_EQ(warped[1].color.at(10, 5, 2), noisy[2].at(11, 5, 2));
  const Image out = temporal_blend(noisy[1], warped, {.tolerance = 0.5});
  double var_in = 0, var_out = 0;
  int64_t count = 0;
  for (int64_t y = 0; y < H; ++y)
    for (int64_t x = 1; x < W - 1; ++x)
      for (int c = 0; c < 3; ++c) {
        const double truth = wall.at(x + 1, y, c);
        var_in += std::pow(noisy[1].at(x, y, c) - truth, 2);
        var_out += std::pow(out.at(x, y, c) - truth, 2);
        ++count;
      }
  EXPECT_NEAR(var_out / var_in, 1.0 / 3.0, 0.05);
}

}  // namespace
}  // namespace residue
