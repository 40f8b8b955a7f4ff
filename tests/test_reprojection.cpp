// Reprojection (core/temporal/reprojection.h) and the motion AOV: exact on integer motion, within bilinear error
// on sub-pixel motion, the identity for a still camera, disocclusions masked; Cycles' Vector pass read in
// Residue's convention; and on a real rendered shot (tests/data/shot: a camera truck and two moving props), the
// previous and next frames' references brought to frame t agree with t's far better than unwarped.
#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "core/aov/aov_loader.h"
#include "core/temporal/reprojection.h"
#include "support/test_support.h"

namespace residue {
namespace {

namespace fs = std::filesystem;
using testing::random_image;

Image constant_motion(int64_t w, int64_t h, float px, float py, float nx, float ny) {
  Image m(w, h, 4);
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x) m.at(x, y, 0) = px, m.at(x, y, 1) = py, m.at(x, y, 2) = nx, m.at(x, y, 3) = ny;
  return m;
}

TEST(Reprojection, IntegerMotionWarpsExactlyAndMasksWhatLeavesTheFrame) {
  const Image previous = random_image(40, 30, 3, 1);
  const Reprojected r = reproject(previous, constant_motion(40, 30, 3, -2, 0, 0), MotionStep::Previous);
  int64_t outside = 0;
  for (int64_t y = 0; y < 30; ++y)
    for (int64_t x = 0; x < 40; ++x) {
      const bool inside = x + 3 < 40 && y - 2 >= 0;
      ASSERT_EQ(r.valid.at(x, y), inside ? 1.0f : 0.0f) << x << "," << y;
      outside += !inside;
      if (!inside) continue;
      for (int c = 0; c < 3; ++c) ASSERT_EQ(r.image.at(x, y, c), previous.at(x + 3, y - 2, c)) << x << "," << y;
    }
  EXPECT_EQ(r.outside, outside);
  EXPECT_EQ(r.disoccluded, 0);
}

TEST(Reprojection, SubPixelMotionIsBilinear) {
  // Bilinear interpolation is exact on a plane: a ramp shifted by (0.3, 1.7) is the ramp at the shifted point.
  Image ramp(32, 32, 1);
  for (int64_t y = 0; y < 32; ++y)
    for (int64_t x = 0; x < 32; ++x) ramp.at(x, y) = 0.25f * static_cast<float>(x) - 0.5f * static_cast<float>(y) + 3.0f;
  const Reprojected r = reproject(ramp, constant_motion(32, 32, 0, 0, 0.3f, 1.7f), MotionStep::Next);
  for (int64_t y = 0; y + 2 < 32; ++y)
    for (int64_t x = 0; x + 1 < 32; ++x) {
      ASSERT_EQ(r.valid.at(x, y), 1.0f);
      const double sx = static_cast<double>(x) + 0.3, sy = static_cast<double>(y) + 1.7;
      ASSERT_NEAR(r.image.at(x, y), 0.25 * sx - 0.5 * sy + 3.0, 1e-5) << x << "," << y;
    }
  // A random image: within the range of the four taps it mixes.
  const Image noise = random_image(32, 32, 1, 7);
  const Reprojected n = reproject(noise, constant_motion(32, 32, 0.5f, 0.5f, 0, 0), MotionStep::Previous);
  for (int64_t y = 0; y + 1 < 32; ++y)
    for (int64_t x = 0; x + 1 < 32; ++x) {
      const float lo = std::min({noise.at(x, y), noise.at(x + 1, y), noise.at(x, y + 1), noise.at(x + 1, y + 1)});
      const float hi = std::max({noise.at(x, y), noise.at(x + 1, y), noise.at(x, y + 1), noise.at(x + 1, y + 1)});
      ASSERT_GE(n.image.at(x, y), lo - 1e-6f);
      ASSERT_LE(n.image.at(x, y), hi + 1e-6f);
    }
}

TEST(Reprojection, AStillCameraIsTheIdentity) {
  const Image frame = random_image(17, 13, 4, 3);
  const Image depth = random_image(17, 13, 1, 4, 1.0f, 9.0f);
  const Reprojected r = reproject(frame, Image(17, 13, 4), MotionStep::Previous, &depth, &depth);
  for (size_t i = 0; i < frame.size(); ++i) ASSERT_EQ(r.image.data()[i], frame.data()[i]);
  EXPECT_EQ(r.outside + r.disoccluded, 0);
}

// A square 2 m away moves 4 px to the right in front of a wall 10 m away: at frame t, the wall it has just
// uncovered was hidden in the previous frame (the square's depth there): masked; the square itself and the rest
// of the wall come from the previous frame.
TEST(Reprojection, DisoccludedPixelsAreMasked) {
  const int64_t W = 40, H = 20;
  Image prev_colour(W, H, 3), prev_depth(W, H, 1), depth(W, H, 1), motion(W, H, 4);
  for (int64_t y = 0; y < H; ++y)
    for (int64_t x = 0; x < W; ++x) {
      const bool square_before = x >= 10 && x < 20 && y >= 5 && y < 15, square_now = x >= 14 && x < 24 && y >= 5 && y < 15;
      prev_depth.at(x, y) = square_before ? 2.0f : 10.0f;
      prev_colour.at(x, y, 0) = square_before ? 1.0f : 0.1f;
      depth.at(x, y) = square_now ? 2.0f : 10.0f;
      motion.at(x, y, 0) = square_now ? -4.0f : 0.0f;  // the square was 4 px to the left
    }
  const Reprojected r = reproject(prev_colour, motion, MotionStep::Previous, &depth, &prev_depth);
  for (int64_t y = 0; y < H; ++y)
    for (int64_t x = 0; x < W; ++x) {
      const bool uncovered = x >= 10 && x < 14 && y >= 5 && y < 15;
      ASSERT_EQ(r.valid.at(x, y), uncovered ? 0.0f : 1.0f) << x << "," << y;
      if (uncovered) continue;
      ASSERT_EQ(r.image.at(x, y, 0), depth.at(x, y) == 2.0f ? 1.0f : 0.1f) << x << "," << y;
    }
  EXPECT_EQ(r.disoccluded, 4 * 10);
  // Normals that turned away (a surface seen from its other side) are masked too.
  Image n_now(W, H, 3), n_prev(W, H, 3);
  for (int64_t y = 0; y < H; ++y)
    for (int64_t x = 0; x < W; ++x) n_now.at(x, y, 2) = 1.0f, n_prev.at(x, y, 2) = x < 5 ? -1.0f : 1.0f;
  EXPECT_EQ(reproject(prev_colour, Image(W, H, 4), MotionStep::Previous, nullptr, nullptr, &n_now, &n_prev).disoccluded,
            5 * H);
}

TEST(Reprojection, CyclesVectorPassInResiduesConvention) {
  // tools/datagen/vector_convention_check.py, frame 2 of the orthographic shot: the square's Vector is
  // (-2, -1, -4, -3): it was 2 px left and 1 px below (rows down: +1), and will be 4 px right and 3 px above.
  Image v(1, 1, 4);
  v.at(0, 0, 0) = -2, v.at(0, 0, 1) = -1, v.at(0, 0, 2) = -4, v.at(0, 0, 3) = -3;
  const Image m = motion_from_cycles_vector(v);
  EXPECT_EQ(m.at(0, 0, 0), -2.0f);
  EXPECT_EQ(m.at(0, 0, 1), 1.0f);
  EXPECT_EQ(m.at(0, 0, 2), 4.0f);
  EXPECT_EQ(m.at(0, 0, 3), -3.0f);
}

// The committed rendered shot: frames t-1 and t+1 of the reference, warped to t along frame t's motion AOV
// (loaded from the noisy render's Vector pass), against the reference of t.
TEST(Reprojection, RealShotNeighboursLandOnFrameT) {
  const fs::path shot = fs::path(RESIDUE_SOURCE_RESOURCES) / ".." / "tests" / "data" / "shot";
  const AovStack t = load_aov_stack({shot / "noisy.0003.exr"}, {});
  ASSERT_TRUE(t.motion.has_value()) << "the Vector pass is recognised as the motion AOV";
  EXPECT_NE(t.motion->source.layer.find("Vector"), std::string::npos) << t.motion->source.layer;
  LoadOptions colour_only;
  colour_only.load_reference = false;
  const auto reference = [&](int f) {
    return load_aov_stack({shot / ("reference.000" + std::to_string(f) + ".exr")}, colour_only).color.image;
  };
  const Image ref_t = reference(3);
  const auto mse = [&](const Image& a, const Image* valid) {
    double sum = 0;
    int64_t n = 0;
    for (int64_t y = 0; y < a.height(); ++y)
      for (int64_t x = 0; x < a.width(); ++x) {
        if (valid && valid->at(x, y) == 0) continue;
        for (int c = 0; c < 3; ++c) sum += std::pow(double{a.at(x, y, c)} - ref_t.at(x, y, c), 2);
        ++n;
      }
    return sum / static_cast<double>(3 * n);
  };
  const auto neighbour = [&](int f) { return load_aov_stack({shot / ("noisy.000" + std::to_string(f) + ".exr")}, {}); };
  const AovStack prev = neighbour(2), next = neighbour(4);
  for (const auto& [f, step, other] : {std::tuple{2, MotionStep::Previous, &prev}, std::tuple{4, MotionStep::Next, &next}}) {
    const Image ref_n = reference(f);
    const Reprojected r = reproject(ref_n, t.motion->image, step, &t.depth->image, &other->depth->image,
                                    &t.normal->image, &other->normal->image);
    const double warped = mse(r.image, &r.valid), unwarped = mse(ref_n, &r.valid);
    std::printf("[ measured ] frame %d to 3: MSE unwarped %.3g, warped %.3g (%.1fx lower); %lld outside, %lld "
                "disoccluded of %lld\n", f, unwarped, warped, unwarped / warped, static_cast<long long>(r.outside),
                static_cast<long long>(r.disoccluded), static_cast<long long>(ref_t.pixel_count()));
    EXPECT_LT(warped, 0.5 * unwarped) << "frame " << f;
    // The signs matter: the motion reversed lands worse than the motion as read.
    Image reversed = t.motion->image;
    for (size_t i = 0; i < reversed.size(); ++i) reversed.data()[i] = -reversed.data()[i];
    const Reprojected wrong = reproject(ref_n, reversed, step);
    EXPECT_GT(mse(wrong.image, &wrong.valid), 2.0 * warped) << "frame " << f;
    EXPECT_LT(r.outside + r.disoccluded, ref_t.pixel_count() / 4) << "most pixels are seen in both frames";
  }
}

}  // namespace
}  // namespace residue
