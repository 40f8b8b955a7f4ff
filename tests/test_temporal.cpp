// Flicker (issue 19): the temporal relMSE against an independent float64 computation, its fixed points, its
// motion-compensated form (issue 51), and `residue-cli eval` on a sequence.
#include <algorithm>
#include <cmath>
#include <functional>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/aov/aov_loader.h"
#include "core/metrics/temporal.h"
#include "core/temporal/reprojection.h"
#include "core/temporal/warped_error.h"
#include "support/exr_fixture.h"
#include "support/test_support.h"

namespace residue {
namespace {

using testing::random_image;

// The definition, written out in float64 over whole frames.
double naive_temporal(const std::vector<Image>& x, const std::vector<Image>& r, double eps) {
  double sum = 0;
  int64_t n = 0;
  for (size_t t = 1; t < x.size(); ++t)
    for (int64_t py = 0; py < x[t].height(); ++py)
      for (int64_t px = 0; px < x[t].width(); ++px) {
        double term = 0;
        bool ok = true;
        for (int c = 0; c < 3; ++c) {
          const double a = x[t].at(px, py, c), b = x[t - 1].at(px, py, c), p = r[t].at(px, py, c), q = r[t - 1].at(px, py, c);
          ok = ok && std::isfinite(a) && std::isfinite(b) && std::isfinite(p) && std::isfinite(q);
          term += std::pow((a - b) - (p - q), 2) / (p * p + eps);
        }
        if (ok) sum += term / 3, ++n;
      }
  return sum / static_cast<double>(n);
}

TEST(Temporal, MatchesTheDefinitionAndExcludesNonFinite) {
  std::vector<Image> x, r;
  for (unsigned t = 0; t < 4; ++t) {
    x.push_back(random_image(23, 17, 3, 10 + t, 0.0f, 3.0f));
    r.push_back(random_image(23, 17, 3, 20 + t, 0.0f, 2.0f));
  }
  x[2].at(5, 6, 1) = std::numeric_limits<float>::quiet_NaN();
  metrics::TemporalRelMse m(0.01);
  EXPECT_TRUE(std::isnan(m.value()));
  for (size_t t = 0; t < x.size(); ++t) m.add(x[t], r[t]);
  EXPECT_EQ(m.pairs(), 3);
  EXPECT_EQ(m.excluded(), 2) << "the NaN pixel in frame 2 spoils the pairs (1,2) and (2,3)";
  EXPECT_EQ(m.pixels(), 3 * 23 * 17 - 2);
  EXPECT_NEAR(m.value(), naive_temporal(x, r, 0.01), 1e-12 * naive_temporal(x, r, 0.01));
}

TEST(Temporal, ZeroWhenTheSequenceChangesAsItsReferencesDo) {
  const Image base = random_image(16, 16, 3, 1, 0.1f, 1.0f);
  const Image shift = random_image(16, 16, 3, 2, 0.0f, 0.5f);
  metrics::TemporalRelMse same(0.01), stable(0.01), flicker(0.01);
  Image moved = base;
  for (size_t i = 0; i < moved.size(); ++i) moved.data()[i] += shift.data()[i];
  same.add(base, base);
  same.add(moved, moved);  // the scene changes; the frames follow exactly
  EXPECT_EQ(same.value(), 0.0);
  stable.add(base, base);
  stable.add(base, base);
  EXPECT_EQ(stable.value(), 0.0);
  flicker.add(base, base);
  flicker.add(moved, base);  // the frame changes, the reference does not: all of it is flicker
  EXPECT_GT(flicker.value(), 0.01);
  EXPECT_FALSE(testing::error_message([&] { flicker.add(Image(8, 8, 3), Image(8, 8, 3)); }, ErrorKind::Usage).empty());
}

// A highlight that moves: one pixel bright (r = 4) at t-1 and dark (r = 0) at t, the output off by 0.5 at t-1
// and exact at t. The error changes by 0.5 there: the r_t form divides by 0 + eps (25), the symmetric form by
// (16 + 0) / 2 + eps (about 0.031): the pixel the highlight has just left no longer dominates (issue 51).
TEST(Temporal, TheSymmetricFormIsNotDominatedByAHighlightThatLeft) {
  Image r0(1, 1, 3), r1(1, 1, 3), x0(1, 1, 3), x1(1, 1, 3);
  for (int c = 0; c < 3; ++c) r0.at(0, 0, c) = 4.0f, x0.at(0, 0, c) = 4.5f, r1.at(0, 0, c) = 0.0f, x1.at(0, 0, c) = 0.0f;
  metrics::TemporalRelMse m(0.01);
  m.add(x0, r0);
  m.add(x1, r1);
  EXPECT_NEAR(m.value(), 0.25 / 0.01, 1e-9);
  EXPECT_NEAR(m.value_symmetric(), 0.25 / (8.0 + 0.01), 1e-12);
}

// A pan: every frame shows the strip 2 px further on, and the error rides on the surfaces (a stable denoise of a
// moving camera). At a fixed pixel the error changes; along the motion it does not.
TEST(Temporal, TheCompensatedFormFollowsTheSurfaces) {
  const int64_t W = 30, H = 8;
  const Image strip = random_image(W + 12, H, 3, 21, 0.2f, 2.0f), error = random_image(W + 12, H, 3, 22, -0.1f, 0.1f);
  auto frame = [&](const Image& from, int t) {
    Image f(W, H, 3);
    for (int64_t y = 0; y < H; ++y)
      for (int64_t x = 0; x < W; ++x)
        for (int c = 0; c < 3; ++c) f.at(x, y, c) = from.at(x + 2 * t, y, c);
    return f;
  };
  metrics::TemporalRelMse fixed;
  metrics::CompensatedTemporalRelMse along;
  Image motion(W, H, 4);
  for (int64_t y = 0; y < H; ++y)
    for (int64_t x = 0; x < W; ++x) motion.at(x, y, 0) = 2.0f;  // each surface was 2 px to the right before
  for (int t = 0; t < 4; ++t) {
    const Image r = frame(strip, t), e = frame(error, t);
    Image x = r;
    for (size_t i = 0; i < x.size(); ++i) x.data()[i] += e.data()[i];
    fixed.add(x, r);
    if (t == 0) continue;
    const Image r_prev = frame(strip, t - 1), e_prev = frame(error, t - 1);
    const Reprojected we = reproject(e_prev, motion, MotionStep::Previous), wr = reproject(r_prev, motion, MotionStep::Previous);
    along.add_pair(x, r, we.image, wr.image, we.valid);
  }
  EXPECT_GT(fixed.value(), 1e-3) << "at a fixed pixel the error moves past";
  EXPECT_LT(along.value(), 1e-12) << "along the motion it is the same error";
  EXPECT_EQ(along.pixels(), 3 * (W - 2) * H) << "the 2 columns each frame brings in have no past";
}

// The per-pixel map on two frames of the committed Cycles shot, against the definition written out in float64:
// frame t-1's error and reference sampled bilinearly where t's motion says the surface was, then the term.
TEST(Temporal, TheCompensatedMapIsTheDefinitionPerPixel) {
  const std::string shot = std::string(RESIDUE_SOURCE_RESOURCES) + "/../tests/data/shot/";
  const auto frame = [&](int f) {
    LoadOptions o;
    o.reference = shot + "reference.000" + std::to_string(f) + ".exr";
    return load_aov_stack({shot + "noisy.000" + std::to_string(f) + ".exr"}, o);
  };
  const AovStack t = frame(3), prev = frame(2);
  ASSERT_TRUE(t.motion && t.reference && prev.reference);
  const Image& x = t.color.image;
  const Image& xp = prev.color.image;
  const Image map = compensated_temporal_map(t, x, prev, xp);
  const double eps = 0.01;
  int64_t checked = 0, masked = 0;
  metrics::CompensatedTemporalRelMse mean;
  mean.add_map(map);
  double sum = 0;
  for (int64_t py = 0; py < t.height(); ++py)
    for (int64_t px = 0; px < t.width(); ++px) {
      const float v = map.at(px, py);
      if (!std::isfinite(v)) {
        ++masked;
        continue;
      }
      sum += v;
      const double sx = static_cast<double>(px) + t.motion->image.at(px, py, 0);
      const double sy = static_cast<double>(py) + t.motion->image.at(px, py, 1);
      const int64_t x0 = static_cast<int64_t>(std::floor(sx)), y0 = static_cast<int64_t>(std::floor(sy));
      const double ax = sx - std::floor(sx), ay = sy - std::floor(sy);
      const auto at = [&](const Image& im, int64_t xx, int64_t yy, int c) {
        xx = std::clamp<int64_t>(xx, 0, im.width() - 1), yy = std::clamp<int64_t>(yy, 0, im.height() - 1);
        return double{im.at(xx, yy, c)};
      };
      double term = 0;
      for (int c = 0; c < 3; ++c) {
        const auto sample = [&](const std::function<double(int64_t, int64_t)>& f) {
          return (1 - ax) * (1 - ay) * f(x0, y0) + ax * (1 - ay) * f(x0 + 1, y0) + (1 - ax) * ay * f(x0, y0 + 1) +
                 ax * ay * f(x0 + 1, y0 + 1);
        };
        const double ep = sample([&](int64_t a, int64_t b) { return at(xp, a, b, c) - at(prev.reference->image, a, b, c); });
        const double rp = sample([&](int64_t a, int64_t b) { return at(prev.reference->image, a, b, c); });
        const double rt = t.reference->image.at(px, py, c);
        const double d = (double{x.at(px, py, c)} - rt) - ep;
        term += d * d / (0.5 * (rt * rt + rp * rp) + eps);
      }
      EXPECT_NEAR(v, term / 3, 1e-4 * (term / 3) + 1e-9) << px << "," << py;
      ++checked;
    }
  EXPECT_GT(checked, t.width() * t.height() / 2);
  EXPECT_GT(masked, 0) << "the shot's truck uncovers the road";
  EXPECT_NEAR(mean.value(), sum / static_cast<double>(checked), 1e-9 * mean.value());
  EXPECT_EQ(mean.pixels(), checked);
}

TEST(TemporalCli, EvalScoresASequenceAndItsFlicker) {
  testing::TempDir dir;
  // A static shot: one reference; the noisy frames carry frame-dependent noise, the "denoised" ones are the
  // reference plus a small constant bias (stable: no flicker).
  for (int f = 1; f <= 4; ++f) {
    auto noise = [f](int x, int y) {
      uint32_t h = (static_cast<uint32_t>(x) * 73856093u) ^ (static_cast<uint32_t>(y) * 19349663u) ^ (static_cast<uint32_t>(f) * 83492791u);
      h ^= h >> 13;
      h *= 0x5bd1e995u;
      return static_cast<float>(h & 0xffu) / 255.0f - 0.5f;
    };
    testing::FixturePart noisy, ref, den;
    noisy.width = noisy.height = ref.width = ref.height = den.width = den.height = 24;
    for (const char* c : {"R", "G", "B"}) {
      noisy.channels.push_back({c, false, [=](int x, int y) { return 0.5f + 0.3f * noise(x, y); }});
      ref.channels.push_back({c, false, [](int, int) { return 0.5f; }});
      den.channels.push_back({c, false, [](int, int) { return 0.52f; }});
    }
    char name[64];
    std::snprintf(name, sizeof name, "noisy.%04d.exr", f);
    testing::write_fixture_exr((dir / name).string(), {noisy});
    std::snprintf(name, sizeof name, "ref.%04d.exr", f);
    testing::write_fixture_exr((dir / name).string(), {ref});
    std::snprintf(name, sizeof name, "den.%04d.exr", f);
    testing::write_fixture_exr((dir / name).string(), {den});
  }
  std::string out;
  ASSERT_EQ(testing::run_cli({"eval", "--json", (dir / "noisy.####.exr").string(), "-r", (dir / "ref.####.exr").string(),
                              "--denoised", (dir / "den.####.exr").string()}, &out), 0) << out;
  const auto j = nlohmann::json::parse(out);
  EXPECT_EQ(j["frames"], 4);
  EXPECT_EQ(j["per_frame"].size(), 4u);
  EXPECT_GT(j["temporal_relmse"]["noisy"].get<double>(), 0.01);
  EXPECT_EQ(j["temporal_relmse"]["denoised"].get<double>(), 0.0) << "a constant bias does not flicker";
  EXPECT_GT(j["mean"]["denoised"]["relmse"].get<double>(), 0.0) << "but it is an error per frame";
  EXPECT_EQ(j["flicker_ratio"].get<double>(), 0.0);
  ASSERT_EQ(testing::run_cli({"eval", (dir / "noisy.####.exr").string(), "-r", (dir / "ref.####.exr").string(), "--frames", "1-3"}, &out), 0) << out;
  EXPECT_NE(out.find("temporal relMSE (flicker): noisy"), std::string::npos) << out;
  EXPECT_EQ(testing::run_cli({"eval", (dir / "noisy.####.exr").string()}, &out), 2) << "references are needed: " << out;
}

}  // namespace
}  // namespace residue
