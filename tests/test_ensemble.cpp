// The self-ensemble (DenoiseOptions::ensemble): the network under flips and transposes, averaged; and the
// dihedral transforms it and the trainer's augmentation share (core/image/dihedral.h).
#include <cmath>

#include <gtest/gtest.h>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoiser.h"
#include "core/image/dihedral.h"
#include "core/metrics/metrics.h"
#include "core/nn/model_file.h"
#include "core/util/error.h"
#include "support/test_support.h"

namespace residue {
namespace {

// A small multi-scale network (alignment 4): pooling is where a flipped tile could land on another grid.
nn::Model multiscale_model(uint32_t seed) {
  nn::Architecture a;
  a.features = FeatureSet::Full;
  a.levels = {1, 1, 2};
  a.widths = {8, 12, 16};
  a.blocks = 1;
  a.width = 8;
  return nn::model_from_network(nn::random_network(a, seed), "ms");
}

// The network with its guard, nothing after it: the energy correction works on a grid of blocks from the
// image's origin, which a flip moves.
DenoiseOptions plain(int ensemble, const std::string& backend = "eigen") {
  DenoiseOptions o;
  o.backend = backend;
  o.ensemble = ensemble;
  o.energy_correction = false;
  o.variance_blend = false;
  return o;
}

// The render under d, as a renderer would have written the turned image: camera-space normals turn with it.
AovStack turned(const AovStack& s, const Dihedral& d) {
  AovStack t = s;
  t.color.image = apply(s.color.image, d);
  t.albedo->image = apply(s.albedo->image, d);
  t.depth->image = apply(s.depth->image, d);
  t.normal->image = apply(s.normal->image, d, 0);
  const auto [w, h] = d.size(s.width(), s.height());
  t.data_window = {0, 0, w, h};
  t.display_width = w;
  t.display_height = h;
  return t;
}

double max_rel_diff(const Image& a, const Image& b) {
  EXPECT_EQ(a.width(), b.width());
  EXPECT_EQ(a.height(), b.height());
  double err = 0;
  for (size_t i = 0; i < a.size(); ++i)
    err = std::max(err, std::abs(static_cast<double>(a.data()[i]) - b.data()[i]) / (1e-3 + std::abs(b.data()[i])));
  return err;
}

double rel_mse(const Image& a, const Image& ref) { return metrics::compare(a, ref).relmse; }

TEST(Dihedral, EachElementIsUndoneByItsInverse) {
  const Image x = testing::random_image(5, 3, 4, 7, -1.0f, 1.0f);
  for (int i = 0; i < 8; ++i) {
    const Dihedral d = Dihedral::from_index(i);
    const Image y = apply(x, d, 1);  // planes 1 and 2 a normal's x, y
    const auto [w, h] = d.size(5, 3);
    EXPECT_EQ(y.width(), w);
    EXPECT_EQ(y.height(), h);
    const Image back = apply(y, d.inverse(), 1);
    for (size_t k = 0; k < x.size(); ++k) ASSERT_EQ(back.data()[k], x.data()[k]) << i;
    // map() says where each source pixel went.
    for (int64_t v = 0; v < 3; ++v)
      for (int64_t u = 0; u < 5; ++u) {
        const Rect r = d.map({u, v, 1, 1}, 5, 3);
        EXPECT_EQ(y.at(r.x, r.y, 0), x.at(u, v, 0)) << i;
        EXPECT_EQ(y.at(r.x, r.y, 3), x.at(u, v, 3)) << i;
      }
    // A rectangle maps to the rectangle of its pixels.
    const Rect r = d.map({1, 0, 3, 2}, 5, 3);
    EXPECT_EQ(r.area(), 6) << i;
  }
}

TEST(Dihedral, NormalsTurnWithTheImage) {
  // View space: x right, y up. Mirroring x turns a surface that faced right to face left; mirroring y, one that
  // faced up to face down; the transpose takes the image's right to its bottom, so right-facing faces down.
  using P = std::pair<float, float>;
  EXPECT_EQ(Dihedral::from_index(1).turn_normal(1, 0), (P{-1, 0}));
  EXPECT_EQ(Dihedral::from_index(1).turn_normal(0, 1), (P{0, 1}));
  EXPECT_EQ(Dihedral::from_index(2).turn_normal(0, 1), (P{0, -1}));
  EXPECT_EQ(Dihedral::from_index(2).turn_normal(1, 0), (P{1, 0}));
  EXPECT_EQ(Dihedral::from_index(4).turn_normal(1, 0), (P{0, -1}));
  EXPECT_EQ(Dihedral::from_index(4).turn_normal(0, 1), (P{-1, 0}));
  for (int i = 0; i < 8; ++i) {
    const Dihedral d = Dihedral::from_index(i);
    const auto [x, y] = d.turn_normal(0.6f, -0.8f);
    const auto [bx, by] = d.inverse().turn_normal(x, y);
    EXPECT_FLOAT_EQ(bx, 0.6f) << i;
    EXPECT_FLOAT_EQ(by, -0.8f) << i;
  }
}

// x N is the mean of N plain denoises of the turned render, each turned back: core turns the feature planes
// (normals included) as a renderer would have written the turned image, and averages linear values.
TEST(Ensemble, IsTheMeanOfTheTurnedDenoises) {
  const nn::Model m = multiscale_model(5);
  const AovStack s = testing::random_stack(48, 32, 4);
  for (int n : {2, 4, 8}) {
    Image mean(48, 32, 3);
    for (int k = 0; k < n; ++k) {
      const Dihedral d = Dihedral::from_index(k);
      const Image back = apply(denoise(turned(s, d), m, plain(1)), d.inverse());
      for (size_t i = 0; i < mean.size(); ++i) mean.data()[i] += back.data()[i] / static_cast<float>(n);
    }
    DenoiseStats stats;
    const Image x = denoise(s, m, plain(n), {}, &stats);
    EXPECT_EQ(stats.ensemble, n);
    EXPECT_LT(max_rel_diff(x, mean), 1e-5) << n;
  }
}

// With all eight, denoising a turned render gives the turned denoise (to rounding); one member does not, by far:
// the test can tell.
TEST(Ensemble, EightMembersMakeTheDenoiseCommuteWithFlips) {
  const nn::Model m = multiscale_model(6);
  const AovStack s = testing::random_stack(48, 32, 9);
  const Image x8 = denoise(s, m, plain(8)), x1 = denoise(s, m, plain(1));
  double worst_single = 0;
  for (int k = 1; k < 8; ++k) {
    const Dihedral d = Dihedral::from_index(k);
    const AovStack t = turned(s, d);
    EXPECT_LT(max_rel_diff(denoise(t, m, plain(8)), apply(x8, d)), 1e-5) << k;
    worst_single = std::max(worst_single, max_rel_diff(denoise(t, m, plain(1)), apply(x1, d)));
  }
  EXPECT_GT(worst_single, 1e-2);
}

// Tiled equals untiled (tiles that do and do not divide a 90 x 61 image, an ROI), both backends; streamed from a
// file equals in memory.
TEST(Ensemble, TiledEqualsUntiledAndStreamed) {
  const nn::Model m = multiscale_model(7);
  const AovStack s = testing::random_stack(90, 61, 2);
  for (const auto& b : nn::available_backends()) {
    DenoiseOptions o = plain(8, b);
    const Image whole = denoise(s, m, o);
    EXPECT_GT(rel_mse(denoise(s, m, plain(1, b)), whole), 1e-6) << b;  // the ensemble changed something
    for (int64_t tile : {24, 40}) {
      o.tile = tile;
      EXPECT_LT(rel_mse(denoise(s, m, o), whole), 1e-11) << b << " tile " << tile;
    }
    o.roi = Rect{13, 7, 50, 41};
    o.tile = 20;
    const Image roi = denoise(s, m, o);
    EXPECT_LT(rel_mse(crop(roi, *o.roi), crop(whole, *o.roi)), 1e-11) << b << " roi";
  }
  const std::filesystem::path room = RESIDUE_TEST_FIXTURES "/../../resources/examples/room/noisy.exr";
  testing::TempDir tmp;
  DenoiseOptions o = plain(4);
  o.energy_correction = true;  // the streamed engine's post-steps, as in memory
  o.tile = 36;
  io::ExrWriteOptions exr;
  exr.pixel_type = io::PixelType::Float;
  const DenoiseStats stats = denoise_to_exr(AovReader({room}), m, o, tmp / "x4.exr", exr);
  EXPECT_EQ(stats.ensemble, 4);
  EXPECT_LT(rel_mse(testing::read_exr_float(tmp / "x4.exr"), denoise(load_aov_stack({room}), m, o)), 1e-11);
}

// A model file can ask for its ensemble (metadata residue.ensemble); the option overrides it; other sizes are
// refused, naming the key or the option.
TEST(Ensemble, ModelsCarryTheirSizeAndBadSizesAreRefused) {
  testing::TempDir tmp;
  nn::SafetensorsFile f = nn::to_safetensors(nn::random_network({1, 8, FeatureSet::Full}, 3));
  f.metadata["residue.ensemble"] = "8";
  nn::write_safetensors(tmp / "x8.safetensors", f, false);
  const nn::Model m = nn::load_model(tmp / "x8.safetensors");
  EXPECT_EQ(m.ensemble, 8);
  const AovStack s = testing::random_stack(20, 12, 1);
  DenoiseStats stats;
  DenoiseOptions o = plain(0);
  denoise(s, m, o, {}, &stats);
  EXPECT_EQ(stats.ensemble, 8);
  o.ensemble = 1;
  denoise(s, m, o, {}, &stats);
  EXPECT_EQ(stats.ensemble, 1);
  o.ensemble = 3;
  EXPECT_NE(testing::error_message([&] { denoise(s, m, o); }, ErrorKind::Usage).find("1, 2, 4 or 8"), std::string::npos);

  f.metadata["residue.ensemble"] = "3";
  nn::write_safetensors(tmp / "x3.safetensors", f, false);
  const std::string e = testing::error_message([&] { nn::load_model(tmp / "x3.safetensors"); }, ErrorKind::Input);
  EXPECT_NE(e.find("residue.ensemble"), std::string::npos) << e;
  EXPECT_NE(e.find("x3.safetensors"), std::string::npos) << e;
}

}  // namespace
}  // namespace residue
