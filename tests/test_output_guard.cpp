// The output guard (core/denoise/output_guard.h): against a brute-force window max, and through denoise()
// with a network made to overshoot and with the shipped model on a real render with an emitter of 1e6.
#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/output_guard.h"
#include "core/features/features.h"
#include "core/nn/model_file.h"
#include "core/nn/model_registry.h"
#include "support/test_support.h"

namespace residue {
namespace {

using testing::random_image;
using testing::random_stack;

// The bound of one output value in log space, by the definition: twice the window's max in linear terms,
// computed in float64.
double naive_bound(const Image& features, int64_t x, int64_t y, int c, int64_t r) {
  double m = -INFINITY;
  for (int64_t sy = std::max<int64_t>(0, y - r); sy <= std::min(features.height() - 1, y + r); ++sy)
    for (int64_t sx = std::max<int64_t>(0, x - r); sx <= std::min(features.width() - 1, x + r); ++sx)
      m = std::max(m, static_cast<double>(features.at(sx, sy, c)));
  return m > 0 ? std::log1p(2.0 * std::expm1(m)) : 0.0;
}

TEST(OutputGuard, ClampsExactlyToTwiceTheWindowMaxInLinearTerms) {
  const Image features = random_image(37, 29, 9, 3, 0.0f, 3.0f);
  for (const Rect tile : {Rect{0, 0, 37, 29}, Rect{5, 4, 20, 11}, Rect{30, 20, 7, 9}})
    for (int64_t r : {0, 1, 5, 40}) {
      Image out = random_image(37, 29, 3, 11, 0.0f, 5.0f);  // about half above the bound
      const Image before = out;
      const int64_t clamped = guard_output(features, tile, r, out);
      int64_t expected = 0;
      for (int64_t y = 0; y < 29; ++y)
        for (int64_t x = 0; x < 37; ++x)
          for (int c = 0; c < 3; ++c) {
            const double v = before.at(x, y, c);
            if (!tile.contains({x, y, 1, 1})) {
              ASSERT_EQ(out.at(x, y, c), before.at(x, y, c)) << "outside the tile nothing changes";
              continue;
            }
            const double bound = naive_bound(features, x, y, c, r);
            expected += v > static_cast<float>(bound);
            ASSERT_FLOAT_EQ(out.at(x, y, c), static_cast<float>(std::min(v, bound))) << x << "," << y << " r " << r;
          }
      EXPECT_EQ(clamped, expected);
      EXPECT_GT(clamped, 0);
    }
}

TEST(OutputGuard, LeavesNaNForTheExpansionToZero) {
  Image features(4, 4, 3);
  Image out(4, 4, 3);
  out.at(1, 1, 0) = std::numeric_limits<float>::quiet_NaN();
  out.at(2, 2, 1) = INFINITY;
  EXPECT_EQ(guard_output(features, {0, 0, 4, 4}, 1, out), 1);
  EXPECT_TRUE(std::isnan(out.at(1, 1, 0)));
  EXPECT_EQ(out.at(2, 2, 1), 0.0f) << "over black, black";
  EXPECT_EQ(expand_color(out.at(1, 1, 0)), 0.0f);
}

// A network whose last conv adds 20 to the log output: e^20 = 5e8 everywhere, an overshoot of every pixel.
nn::Model overshooting_model() {
  nn::Network n = nn::random_network({2, 8, FeatureSet::Full}, 4);
  for (float& b : n.out.bias) b += 20.0f;
  return nn::model_from_network(std::move(n), "overshoot");
}

TEST(OutputGuard, BoundsADenoiseByTheBrightestInputInTheReceptiveField) {
  const nn::Model model = overshooting_model();
  const int64_t halo = model.network.arch.halo();
  AovStack s = random_stack(48, 40, 5);
  s.color.image.at(10, 12, 1) = 1e6f;  // a firefly raises the bound around it, and only there
  DenoiseOptions o;
  o.backend = "eigen";
  o.energy_correction = false;
  o.output_guard = false;
  o.tile = 64;
  const Image raw = denoise(s, model, o);
  o.output_guard = true;
  DenoiseStats stats;
  const Image guarded = denoise(s, model, o, {}, &stats);
  EXPECT_GT(*std::max_element(raw.data(), raw.data() + raw.size()), 1e8f) << "without the guard it overshoots";
  EXPECT_EQ(stats.guarded_values, 48 * 40 * 3);
  for (int64_t y = 0; y < 40; ++y)
    for (int64_t x = 0; x < 48; ++x)
      for (int c = 0; c < 3; ++c) {
        double window_max = 0;  // linear, float64
        for (int64_t sy = std::max<int64_t>(0, y - halo); sy <= std::min<int64_t>(39, y + halo); ++sy)
          for (int64_t sx = std::max<int64_t>(0, x - halo); sx <= std::min<int64_t>(47, x + halo); ++sx)
            window_max = std::max(window_max, static_cast<double>(s.color.image.at(sx, sy, c)));
        ASSERT_NEAR(guarded.at(x, y, c), 2.0 * window_max, 1e-5 * (2.0 * (1.0 + window_max)))
            << "(" << x << "," << y << ") channel " << c;
      }
  // Tiles see the same windows: their halo is the guard's radius.
  o.tile = 16;
  const Image tiled = denoise(s, model, o);
  for (size_t i = 0; i < tiled.size(); ++i) ASSERT_EQ(tiled.data()[i], guarded.data()[i]) << i;
}

TEST(OutputGuard, TheShippedModelOnARealRenderWithAnEmitterOf1e6) {
  const auto dir = testing::shared_dataset("cycles-starter/s158");
  RESIDUE_REQUIRE_SHARED(dir);
  AovStack s = load_aov_stack({dir / "noisy_a.exr"});
  for (int64_t y = 100; y < 104; ++y)
    for (int64_t x = 120; x < 124; ++x)
      for (int c = 0; c < 3; ++c) s.color.image.at(x, y, c) = c == 2 ? 1e6f : 3e5f;
  const nn::Model model = nn::load_model(nn::find_model("small"));
  DenoiseOptions o;
  o.energy_correction = false;
  DenoiseStats stats;
  const Image out = denoise(s, model, o, {}, &stats);
  const int64_t halo = model.network.arch.halo();
  float far_max = 0;
  for (int64_t y = 0; y < out.height(); ++y)
    for (int64_t x = 0; x < out.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        const float v = out.at(x, y, c);
        ASSERT_TRUE(std::isfinite(v) && v >= 0) << x << "," << y;
        ASSERT_LE(v, 2.0f * (c == 2 ? 1e6f : 3e5f) * (1 + 1e-6f));
        if (std::abs(x - 121) > halo + 2 || std::abs(y - 101) > halo + 2) far_max = std::max(far_max, v);
      }
  EXPECT_LT(far_max, 1e3f) << "the emitter's bound reaches no further than the receptive field";
}

}  // namespace
}  // namespace residue
