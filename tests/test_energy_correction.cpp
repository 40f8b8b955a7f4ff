// The energy correction (core/denoise/energy_correction): against a float64 full-resolution Gaussian written
// out naively, band by band equal to whole, extremes bounded and local, and on a real render with the shipped
// model: the output's mean follows the noisy input's.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/energy_correction.h"
#include "core/nn/model_file.h"
#include "core/nn/model_registry.h"
#include "tests/support/test_support.h"

namespace residue {
namespace {

// A smooth field with a zero-mean high-frequency pattern on top (what noise looks like after blurring), times
// a gain that may wobble at the blur's scale.
Image field(int64_t w, int64_t h, double gain, double noise, double wobble = 0.0, double scale = 1.0) {
  Image img(w, h, 3);
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        const double smooth = (1.0 + 0.5 * std::sin(static_cast<double>(x) / 23.0 + c)) *
                              (1.0 + 0.3 * std::cos(static_cast<double>(y) / 17.0));
        const double pattern = static_cast<double>((x * 7 + y * 13 + c * 5) % 11) / 5.0 - 1.0;  // in [-1, 1]
        const double g = gain * (1.0 + wobble * std::sin((static_cast<double>(x) / 9.0 + static_cast<double>(y) / 13.0) / scale));
        img.at(x, y, c) = static_cast<float>(g * smooth * (1.0 + noise * pattern));
      }
  return img;
}

// The correction as the header defines it, at full resolution in float64: out * G(clamped noisy) / G(out),
// the noisy input clamped to +-16 x the output's luminance, the ratio clamped to [1/4, 4] (the blurs'
// normalisation cancels in the ratio).
Image naive_correction(const Image& noisy, const Image& out, double sigma) {
  const int64_t w = out.width(), h = out.height();
  Image result = out;
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x) {
      double n[3] = {0, 0, 0}, d[3] = {0, 0, 0};
      for (int64_t v = 0; v < h; ++v)
        for (int64_t u = 0; u < w; ++u) {
          const double g = std::exp(-0.5 * static_cast<double>((u - x) * (u - x) + (v - y) * (v - y)) / (sigma * sigma));
          const double lum = 0.2126 * out.at(u, v, 0) + 0.7152 * out.at(u, v, 1) + 0.0722 * out.at(u, v, 2);
          const double limit = 16.0 * std::max(lum, 1e-6);
          for (int c = 0; c < 3; ++c) {
            n[c] += g * std::clamp<double>(noisy.at(u, v, c), -limit, limit);
            d[c] += g * out.at(u, v, c);
          }
        }
      for (int c = 0; c < 3; ++c)
        result.at(x, y, c) = static_cast<float>(out.at(x, y, c) * std::clamp(n[c] / d[c], 0.25, 4.0));
    }
  return result;
}

Image corrected(const Image& noisy, Image out, const Rect& region) {
  EnergyCorrection e(region);
  e.accumulate(noisy, 0, out, 0, 0, noisy.height());
  e.apply(out, 0, 0, out.height());
  return out;
}

double mean(const Image& img) {
  double s = 0;
  for (size_t i = 0; i < img.size(); ++i) s += img.data()[i];
  return s / static_cast<double>(img.size());
}

TEST(EnergyCorrection, MatchesAFloat64FullResolutionGaussian) {
  const Image noisy = field(96, 80, 1.0, 0.6);
  // A 15 % darker "denoised" image whose loss varies by +-30 % over about 150 px, then over 60 px (the blur's
  // own scale, where the block grid is a coarser approximation).
  for (double scale : {2.6, 1.0}) {
    const Image out = field(96, 80, 0.85, 0.05, 0.3, scale);
    const Image ref = naive_correction(noisy, out, 16.0);
    const Image got = corrected(noisy, out, noisy.bounds());
    double worst = 0;
    for (size_t i = 0; i < ref.size(); ++i)
      worst = std::max(worst, std::abs(static_cast<double>(got.data()[i]) / ref.data()[i] - 1.0));
    // Measured 0.6-0.8 %, borders included; sigma 2.5 blocks instead of 2, or 16-px blocks, cost 2-5 %.
    EXPECT_LT(worst, 0.01) << "loss varying over " << 60 * scale << " px";
    EXPECT_NEAR(mean(got) / mean(ref), 1.0, 0.002);
    EXPECT_NEAR(mean(got) / mean(noisy), 1.0, 0.015) << "the 15 % loss is put back";
    EXPECT_LT(mean(out) / mean(noisy), 0.92) << "the output was darker";
  }
}

TEST(EnergyCorrection, BandByBandEqualsWhole) {
  const Image noisy = field(70, 150, 2.0, 0.8);
  const Image out = field(70, 150, 1.7, 0.1);
  const Rect region{5, 9, 60, 131};
  const Image whole = corrected(noisy, out, region);
  for (int64_t band : {1, 7, 40}) {
    EnergyCorrection e(region);
    Image banded = out;
    int64_t added = 0;
    for (int64_t y0 = 0; y0 < 150; y0 += band) {
      const int64_t rows = std::min(band, 150 - y0);
      while (added < std::max(y0 + rows, e.rows_required(y0 + rows))) {
        e.accumulate(noisy, 0, out, 0, added, band);
        added += band;
      }
      e.apply(banded, 0, y0, rows);
    }
    for (size_t i = 0; i < whole.size(); ++i) ASSERT_EQ(banded.data()[i], whole.data()[i]) << "bands of " << band;
  }
  for (int64_t y = 0; y < 150; ++y)
    for (int64_t x = 0; x < 70; ++x)
      if (!region.contains({x, y, 1, 1})) {
        ASSERT_EQ(whole.at(x, y, 1), out.at(x, y, 1)) << "outside the region";
      }
}

TEST(EnergyCorrection, ExtremesStayBoundedAndLocal) {
  const Image noisy = field(200, 200, 1.0, 0.5);
  const Image out = field(200, 200, 0.9, 0.0);
  const Image base = corrected(noisy, out, noisy.bounds());
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  for (float spoil : {1e6f, std::numeric_limits<float>::max(), nan, inf, -1e6f}) {
    Image bad = noisy;
    bad.at(100, 100, 1) = spoil;
    const Image got = corrected(bad, out, noisy.bounds());
    double worst = 0;
    for (int64_t y = 0; y < 200; ++y)
      for (int64_t x = 0; x < 200; ++x)
        for (int c = 0; c < 3; ++c) {
          ASSERT_TRUE(std::isfinite(got.at(x, y, c))) << spoil;
          const double change = std::abs(got.at(x, y, c) / base.at(x, y, c) - 1.0);
          worst = std::max(worst, change);
          // The blur reaches kRadiusBlocks blocks, the pixel's own block and the interpolation one more each.
          constexpr int64_t reach = (EnergyCorrection::kRadiusBlocks + 2) * EnergyCorrection::kBlock;
          if (std::abs(x - 100) > reach || std::abs(y - 100) > reach) {
            ASSERT_EQ(change, 0.0) << spoil << " at " << x << "," << y;
          }
        }
    EXPECT_LT(worst, 0.05) << spoil << ": one pixel changes its surroundings by a few percent at most";
  }
  // Black in, black out; a black output stays black whatever the noisy input holds.
  const Image black(40, 30, 3, 0.0f);
  const Image b = corrected(black, black, black.bounds());
  EXPECT_EQ(mean(b), 0.0);
  EXPECT_EQ(mean(corrected(noisy, Image(200, 200, 3, 0.0f), noisy.bounds())), 0.0);
  // Tiny images and regions.
  for (auto [w, h] : std::vector<std::pair<int64_t, int64_t>>{{1, 1}, {3, 5}, {17, 1}}) {
    const Image n = field(w, h, 1.0, 0.0), o = field(w, h, 0.5, 0.0);
    const Image r = corrected(n, o, n.bounds());
    for (size_t i = 0; i < r.size(); ++i) EXPECT_NEAR(r.data()[i], n.data()[i], 1e-5) << w << "x" << h;
  }
}

TEST(EnergyCorrection, TheShippedModelKeepsTheNoisyMeanOnARealRender) {
  const auto dir = testing::shared_dataset("cycles-starter/s158");
  RESIDUE_REQUIRE_SHARED(dir);
  const AovStack s = load_aov_stack({dir / "noisy_a.exr"});
  const nn::Model model = nn::load_model(nn::find_model("small"));
  DenoiseOptions o;
  o.energy_correction = false;
  const Image raw = denoise(s, model, o);
  o.energy_correction = true;
  DenoiseStats stats;
  const Image fixed = denoise(s, model, o, {}, &stats);
  EXPECT_TRUE(stats.energy_corrected);
  // Per channel, the corrected output's mean is the noisy input's (fireflies aside), the raw one's is not.
  const double noisy_mean = mean(s.color.image);
  EXPECT_NEAR(mean(fixed) / noisy_mean, 1.0, 0.005);
  EXPECT_GT(std::abs(mean(raw) / noisy_mean - 1.0), std::abs(mean(fixed) / noisy_mean - 1.0));
  double change = 0;
  for (size_t i = 0; i < raw.size(); ++i) change = std::max(change, std::abs(static_cast<double>(fixed.data()[i]) - raw.data()[i]) / (raw.data()[i] + 1e-2));
  EXPECT_GT(change, 1e-4) << "the correction did something";
  EXPECT_LT(change, 1.0) << "and stayed a correction";
}

}  // namespace
}  // namespace residue
