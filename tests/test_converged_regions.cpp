// Work only where the scene needs it (core/denoise/converged_regions, DenoiseOptions::skip_converged): which
// blocks need the network, the fade into the noisy colour, the rectangles and what they cost, and a denoise with
// it: the noisy colour where converged, the ordinary denoise elsewhere, bit for bit where nothing converged.
#include <gtest/gtest.h>
#include <OpenImageIO/imageio.h>

#include <cmath>
#include <limits>

#include "core/denoise/converged_regions.h"
#include "core/denoise/denoiser.h"
#include "core/nn/model_file.h"
#include "core/util/error.h"
#include "tests/support/exr_fixture.h"
#include "tests/support/test_support.h"

namespace residue {
namespace {

// A w x h stack of colour about 0.5 whose variance is `noisy_var` where `noisy(x, y)` and 0 elsewhere.
template <class F>
AovStack stack_where(int64_t w, int64_t h, float noisy_var, F noisy) {
  AovStack s;
  s.convention = "test";
  s.color.image = testing::random_image(w, h, 3, 11, 0.3f, 0.7f);
  s.variance = Aov{Image(w, h, 3), {}, {}, 0};
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) s.variance->image.at(x, y, c) = noisy(x, y) ? noisy_var : 0.0f;
  s.data_window = {0, 0, w, h};
  s.display_width = w;
  s.display_height = h;
  return s;
}

TEST(ConvergedRegions, BlocksFadeAndRectangles) {
  // The right half is noisy (relative variance ~0.04 / 0.26, far above 1e-4), the left half converged.
  const AovStack s = stack_where(256, 128, 0.04f, [](int64_t x, int64_t) { return x >= 128; });
  const ConvergedPlan plan = plan_converged(s, {0, 0, 256, 128}, 1e-4f, 0);
  // Pixels 3 px left of x = 128 see the noisy half in their 7 x 7 box, so the block 112..127 needs the network
  // too; the weight falls from 1 at x = 112 to 0 at x = 96 (16 px) and is 0 left of it.
  EXPECT_EQ(plan.weight.at(112, 50, 0), 1.0f);
  EXPECT_EQ(plan.weight.at(255, 0, 0), 1.0f);
  EXPECT_FLOAT_EQ(plan.weight.at(100, 50, 0), 1.0f - 12.0f / 16.0f);
  EXPECT_EQ(plan.weight.at(96, 50, 0), 0.0f);
  EXPECT_EQ(plan.weight.at(0, 127, 0), 0.0f);
  EXPECT_EQ(plan.kept_pixels, 97 * 128) << "x = 0..96";
  ASSERT_EQ(plan.regions.size(), 1u);
  EXPECT_EQ(plan.regions.front(), (Rect{96, 0, 160, 128})) << "the blocks with any weight";

  // Nothing converged: the region itself, one rectangle.
  const AovStack all = stack_where(100, 70, 0.04f, [](int64_t, int64_t) { return true; });
  const ConvergedPlan whole = plan_converged(all, {0, 0, 100, 70}, 1e-4f, 35);
  ASSERT_EQ(whole.regions.size(), 1u);
  EXPECT_EQ(whole.regions.front(), (Rect{0, 0, 100, 70}));
  EXPECT_EQ(whole.kept_pixels, 0);

  // Two noisy corners of a large image: two rectangles cost less than their bounding box (halo 20), and
  // a halo wider than the gap makes one rectangle the cheaper plan.
  const AovStack corners = stack_where(512, 512, 0.04f, [](int64_t x, int64_t y) { return (x < 64 && y < 64) || (x >= 448 && y >= 448); });
  const ConvergedPlan two = plan_converged(corners, {0, 0, 512, 512}, 1e-4f, 20);
  ASSERT_EQ(two.regions.size(), 2u);
  const Rect box{0, 0, 512, 512};
  EXPECT_EQ(two.network_pixels, 2 * 116 * 116) << "96 px each (64, the box's 3 px in the next block, the fade's block) and 20 of halo inside";
  EXPECT_LT(two.network_pixels, network_pixels({box}, 20, box) / 9);
  const ConvergedPlan one = plan_converged(corners, {0, 0, 512, 512}, 1e-4f, 400);
  EXPECT_EQ(one.regions.size(), 1u);

  // Noise all round a converged middle (a 48 px border): no single cut of the bounding box lowers the cost,
  // its four sides do. Each covers 80 px (the border's 3 blocks, the 7 x 7 box's 3 px in the next, the fade's);
  // the middle kept is 354 px across (x = 79..432: the fade reaches 0 16 px beyond the blocks needing the network).
  const AovStack ring = stack_where(512, 512, 0.04f, [](int64_t x, int64_t y) { return x < 48 || y < 48 || x >= 464 || y >= 464; });
  const ConvergedPlan sides = plan_converged(ring, {0, 0, 512, 512}, 1e-4f, 20);
  EXPECT_EQ(sides.regions.size(), 4u);
  EXPECT_EQ(sides.kept_pixels, 354 * 354);
  EXPECT_EQ(sides.network_pixels, 2 * 512 * (80 + 20) + 2 * (80 + 20) * (352 + 2 * 20)) << "halos inside the image only";
  EXPECT_LT(sides.network_pixels, network_pixels({box}, 20, box) * 7 / 10);
  // Every pixel with a weight lies in a rectangle.
  for (const ConvergedPlan* p : {&plan, &two, &one, &sides})
    for (int64_t y = 0; y < p->weight.height(); ++y)
      for (int64_t x = 0; x < p->weight.width(); ++x) {
        if (p->weight.at(x, y, 0) == 0.0f) continue;
        bool inside = false;
        for (const Rect& r : p->regions) inside = inside || r.contains({x, y, 1, 1});
        ASSERT_TRUE(inside) << x << "," << y;
      }
}

TEST(ConvergedRegions, ANonFinitePixelNeedsTheNetwork) {
  AovStack s = stack_where(64, 64, 0.04f, [](int64_t, int64_t) { return false; });
  s.color.image.at(40, 40, 1) = std::numeric_limits<float>::quiet_NaN();
  const ConvergedPlan plan = plan_converged(s, {0, 0, 64, 64}, 1e-4f, 0);
  EXPECT_EQ(plan.weight.at(40, 40, 0), 1.0f);
  EXPECT_EQ(plan.weight.at(0, 0, 0), 0.0f);
}

TEST(ConvergedRegions, DenoiseKeepsTheConvergedAndDenoisesTheRest) {
  const nn::Model model = nn::model_from_network(nn::random_network({2, 8, FeatureSet::ColorOnly}, 4));
  // An L of noise (one rectangle) and a frame of noise round a converged middle (its sides, several).
  for (const bool frame : {false, true}) {
    SCOPED_TRACE(frame ? "frame" : "L");
    const int64_t W = frame ? 256 : 160, H = frame ? 192 : 96;
    const AovStack s = stack_where(W, H, 0.04f, [&](int64_t x, int64_t y) {
      return frame ? x < 16 || y < 16 || x >= W - 16 || y >= H - 16 : x >= 96 || y >= 80;
    });
    DenoiseOptions o;
    o.backend = "eigen";
    o.energy_correction = false;  // a local mean over the region would differ at its border; the network does not
    o.tile = 48;
    const Image plain = denoise(s, model, o);
    o.skip_converged = 1e-4f;
    DenoiseStats st;
    const Image skipped = denoise(s, model, o, {}, &st);
    const ConvergedPlan plan = plan_converged(s, {0, 0, W, H}, 1e-4f, model.graph.halo());
    EXPECT_EQ(st.converged_pixels, plan.kept_pixels);
    EXPECT_GT(st.converged_pixels, 0);
    EXPECT_EQ(st.regions, static_cast<int64_t>(plan.regions.size()));
    for (int64_t y = 0; y < H; ++y)
      for (int64_t x = 0; x < W; ++x) {
        const float w = plan.weight.at(x, y, 0);
        for (int c = 0; c < 3; ++c) {
          const float noisy = s.color.image.at(x, y, c), den = plain.at(x, y, c), got = skipped.at(x, y, c);
          if (w == 0.0f) {
            ASSERT_EQ(got, noisy) << x << "," << y << ": kept as rendered";
          } else if (w == 1.0f) {
            ASSERT_NEAR(got, den, 1e-5f) << x << "," << y << ": the ordinary denoise";
          } else {
            ASSERT_NEAR(got, noisy + w * (den - noisy), 1e-5f) << x << "," << y << ": the fade";
          }
        }
      }
    if (frame) {
      EXPECT_GT(st.regions, 1);
    }
  }
  DenoiseOptions o;
  o.backend = "eigen";
  o.tile = 48;
  DenoiseStats st;
  // Nothing converged (every pixel noisy): the ordinary denoise, bit for bit, energy correction on.
  const AovStack all = stack_where(160, 96, 0.04f, [](int64_t, int64_t) { return true; });
  o.energy_correction = true;
  o.skip_converged = 0;
  const Image ordinary = denoise(all, model, o);
  o.skip_converged = 1e-4f;
  const Image none = denoise(all, model, o, {}, &st);
  EXPECT_EQ(st.converged_pixels, 0);
  EXPECT_EQ(st.regions, 1);
  ASSERT_EQ(none.size(), ordinary.size());
  EXPECT_TRUE(std::equal(none.data(), none.data() + none.size(), ordinary.data()));
}

TEST(ConvergedRegions, ARenderWithoutVarianceOrABadThresholdIsRefused) {
  const nn::Model model = nn::model_from_network(nn::random_network({2, 8, FeatureSet::ColorOnly}, 4));
  AovStack s = stack_where(32, 32, 0.04f, [](int64_t, int64_t) { return true; });
  s.color.source.file = "render.exr";
  DenoiseOptions o;
  o.backend = "eigen";
  o.skip_converged = -1.0f;
  EXPECT_NE(testing::error_message([&] { denoise(s, model, o); }, ErrorKind::Usage).find("--skip-converged"), std::string::npos);
  s.variance.reset();
  o.skip_converged = 1e-4f;
  const std::string e = testing::error_message([&] { denoise(s, model, o); }, ErrorKind::Input);
  EXPECT_NE(e.find("render.exr"), std::string::npos) << e;
  EXPECT_NE(e.find("variance"), std::string::npos) << e;
}

// End to end: a render whose variance layer says its left part has converged; the option's report and header,
// the kept pixels as rendered, and the refusals naming what is missing.
TEST(ConvergedRegionsCli, KeepsTheConvergedPartOfARender) {
  testing::TempDir dir;
  testing::FixturePart part;
  part.width = 384;
  part.height = 192;
  const char* rgb[] = {"R", "G", "B"};
  for (int c = 0; c < 3; ++c) {
    part.channels.push_back({rgb[c], false, [c](int x, int y) {
      const uint32_t h = (static_cast<uint32_t>(x) * 73856093u) ^ (static_cast<uint32_t>(y) * 19349663u) ^ (static_cast<uint32_t>(c) * 83492791u);
      return 0.3f + 0.4f * static_cast<float>((h >> 7) & 0xffffu) / 65535.0f;
    }});
    part.channels.push_back({std::string("variance.") + rgb[c], false, [](int x, int) { return x < 192 ? 0.0f : 0.04f; }});
  }
  testing::write_fixture_exr((dir / "render.exr").string(), {part});
  std::string out;
  ASSERT_EQ(testing::run_cli({"denoise", (dir / "render.exr").string(), "-m", "base", "--float", "--skip-converged", "1e-4",
                              "-o", (dir / "out.exr").string()}, &out), 0) << out;
  EXPECT_NE(out.find("of the pixels kept as rendered"), std::string::npos) << out;
  // What the network computed: the noisy part's blocks and their fade (x >= 160) and the halo left of them.
  const size_t at = out.find("% of the image with its halo");
  ASSERT_NE(at, std::string::npos) << out;
  const double share = std::stod(out.substr(out.rfind(", ", at) + 2));
  EXPECT_GT(share, 100.0 * 224 / 384) << out;
  EXPECT_LT(share, 100.0 * (224 + 64) / 384) << out;
  const Image in = testing::read_exr_float(dir / "render.exr"), den = testing::read_exr_float(dir / "out.exr");
  for (int64_t y = 0; y < 192; ++y)
    for (int64_t x = 0; x < 160; ++x)  // the fade ends 32 px left of the noisy part (its box, then 16 px)
      for (int c = 0; c < 3; ++c) ASSERT_EQ(den.at(x, y, c), in.at(x, y, c)) << x << "," << y;
  bool denoised = false;
  for (int64_t x = 200; x < 384 && !denoised; ++x) denoised = den.at(x, 40, 0) != in.at(x, 40, 0);
  EXPECT_TRUE(denoised) << "the noisy part went through the network";
  auto file = OIIO::ImageInput::open((dir / "out.exr").string());
  ASSERT_TRUE(file);
  EXPECT_EQ(file->spec().get_float_attribute("residue:skip_converged"), 1e-4f);
  file->close();

  // A render without variance: nothing says where it converged.
  testing::FixturePart plain = part;
  plain.channels.resize(0);
  for (int c = 0; c < 3; ++c) plain.channels.push_back(part.channels[static_cast<size_t>(2 * c)]);
  testing::write_fixture_exr((dir / "plain.exr").string(), {plain});
  EXPECT_EQ(testing::run_cli({"denoise", (dir / "plain.exr").string(), "-m", "base", "--skip-converged", "1e-4", "-o",
                              (dir / "out2.exr").string()}, &out), 3) << out;
  EXPECT_NE(out.find("plain.exr' has no variance AOV"), std::string::npos) << out;
  // Streamed band by band (3.5 MB as float: more than --max-memory): refused, saying how to hold it.
  EXPECT_EQ(testing::run_cli({"denoise", (dir / "render.exr").string(), "-m", "base", "--skip-converged", "1e-4", "--max-memory",
                              "1", "-o", (dir / "out3.exr").string()}, &out), 2) << out;
  EXPECT_NE(out.find("raise --max-memory"), std::string::npos) << out;
  EXPECT_EQ(testing::run_cli({"denoise", (dir / "render.exr").string(), "-m", "base", "--skip-converged", "0", "-o",
                              (dir / "out4.exr").string()}, &out), 2) << out;
  EXPECT_FALSE(std::filesystem::exists(dir / "out2.exr") || std::filesystem::exists(dir / "out3.exr") ||
               std::filesystem::exists(dir / "out4.exr"));
}

}  // namespace
}  // namespace residue
