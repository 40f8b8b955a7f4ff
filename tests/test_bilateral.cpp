// The cross-bilateral baseline: smooths noise, keeps edges the AOVs show, survives bad pixels.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "core/denoise/bilateral.h"
#include "core/metrics/metrics.h"
#include "support/test_support.h"

namespace residue {
namespace {

// Left half albedo 0.2, right half 0.8; the colour is albedo plus noise.
AovStack two_regions(int64_t w, int64_t h) {
  AovStack s;
  Image noise = testing::random_image(w, h, 3, 3, -0.1f, 0.1f);
  s.color.image = Image(w, h, 3);
  s.albedo = Aov{Image(w, h, 3), {}, {}, 0};
  s.normal = Aov{Image(w, h, 3), {}, {}, 0};
  s.depth = Aov{Image(w, h, 1, 5.0f), {}, {}, 0};
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        const float a = x < w / 2 ? 0.2f : 0.8f;
        s.albedo->image.at(x, y, c) = a;
        s.color.image.at(x, y, c) = a + noise.at(x, y, c);
        s.normal->image.at(x, y, 2) = 1.0f;
      }
  return s;
}

TEST(Bilateral, SmoothsNoiseAndKeepsAlbedoEdges) {
  const AovStack s = two_regions(40, 30);
  const Image out = cross_bilateral(s);
  Image clean(40, 30, 3);
  for (int64_t y = 0; y < 30; ++y)
    for (int64_t x = 0; x < 40; ++x)
      for (int c = 0; c < 3; ++c) clean.at(x, y, c) = s.albedo->image.at(x, y, c);
  const double before = metrics::compare(s.color.image, clean).mse;
  const double after = metrics::compare(out, clean).mse;
  EXPECT_LT(after, 0.1 * before) << "noise variance falls at least 10x";
  // Right at the edge the two sides do not bleed into each other.
  EXPECT_NEAR(out.at(19, 15, 0), 0.2f, 0.03f);
  EXPECT_NEAR(out.at(20, 15, 0), 0.8f, 0.03f);
}

TEST(Bilateral, BadPixelsGiveFiniteNonNegativeOutput) {
  AovStack s = two_regions(16, 16);
  s.color.image.at(3, 3, 0) = std::numeric_limits<float>::quiet_NaN();
  s.color.image.at(4, 3, 1) = std::numeric_limits<float>::infinity();
  s.color.image.at(5, 3, 2) = -7.0f;
  s.albedo->image.at(6, 6, 0) = std::numeric_limits<float>::quiet_NaN();
  s.normal->image.at(7, 7, 1) = std::numeric_limits<float>::infinity();
  s.depth->image.at(8, 8) = std::numeric_limits<float>::quiet_NaN();
  const Image out = cross_bilateral(s);
  for (size_t i = 0; i < out.size(); ++i) {
    ASSERT_TRUE(std::isfinite(out.data()[i])) << i;
    ASSERT_GE(out.data()[i], 0.0f) << i;
  }
}

TEST(Bilateral, ColourOnlyAndRoi) {
  AovStack s = two_regions(20, 20);
  s.albedo.reset();
  s.normal.reset();
  s.depth.reset();
  const Image out = cross_bilateral(s, {}, Rect{5, 5, 4, 4});
  EXPECT_EQ(out.at(0, 0, 0), s.color.image.at(0, 0, 0)) << "outside the ROI the colour stays";
  EXPECT_NE(out.at(6, 6, 0), s.color.image.at(6, 6, 0));
}

}  // namespace
}  // namespace residue
