// Denoising strength (issue 19): 0 gives the input, 1 the output, a linear blend between that keeps the mean,
// the same in memory, streamed and from the CLI, and error that falls as the strength rises on a real render.
#include <gtest/gtest.h>
#include <OpenImageIO/imageio.h>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/strength.h"
#include "core/metrics/metrics.h"
#include "core/nn/model_file.h"
#include "core/nn/model_registry.h"
#include "support/test_support.h"

namespace residue {
namespace {

namespace fs = std::filesystem;

const fs::path kRoom = fs::path(RESIDUE_SOURCE_RESOURCES) / "examples/room/noisy.exr";

double max_abs_diff(const Image& a, const Image& b) {
  EXPECT_EQ(a.size(), b.size());
  double m = 0;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i) m = std::max(m, std::abs(double(a.data()[i]) - double(b.data()[i])));
  return m;
}

double mean(const Image& img) {
  double s = 0;
  for (size_t i = 0; i < img.size(); ++i) s += img.data()[i];
  return s / static_cast<double>(img.size());
}

TEST(Strength, EndsAreTheInputsAndTheBlendKeepsTheMean) {
  const Image noisy = testing::random_image(40, 30, 3, 1, 0.0f, 8.0f);
  const Image denoised = testing::random_image(40, 30, 3, 2, 0.0f, 2.0f);
  EXPECT_EQ(max_abs_diff(with_strength(noisy, denoised, 0.0f), noisy), 0.0);
  EXPECT_EQ(max_abs_diff(with_strength(noisy, denoised, 1.0f), denoised), 0.0);
  for (float s : {0.1f, 0.5f, 0.9f}) {
    const Image b = with_strength(noisy, denoised, s);
    // Linear radiance: the mean of the blend is the blend of the means (a blend of logs would be darker).
    EXPECT_NEAR(mean(b), s * mean(denoised) + (1 - s) * mean(noisy), 1e-5) << s;
  }
  Image bad = noisy;
  bad.at(3, 4, 1) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(with_strength(bad, denoised, 0.3f).at(3, 4, 1), denoised.at(3, 4, 1)) << "a NaN input keeps the output";
  EXPECT_FALSE(testing::error_message([&] { with_strength(noisy, denoised, 1.5f); }, ErrorKind::Usage).empty());
  EXPECT_FALSE(testing::error_message([&] { with_strength(noisy, denoised, std::nanf("")); }, ErrorKind::Usage).empty());
}

class StrengthDenoise : public ::testing::Test {
 protected:
  void SetUp() override {
    LoadOptions lo;
    lo.reference = kRoom.parent_path() / "reference.exr";
    stack_ = load_aov_stack({kRoom}, lo);
    model_ = nn::load_model(nn::find_model_for("tiny", FeatureSet::Full));
    options_.backend = "eigen";
    options_.tile = 128;
  }
  Image run(float strength) {
    DenoiseOptions o = options_;
    o.strength = strength;
    return denoise(stack_, model_, o);
  }
  AovStack stack_;
  nn::Model model_;
  DenoiseOptions options_;
};

TEST_F(StrengthDenoise, IsTheLastStepInMemoryAndStreamed) {
  const Image full = run(1.0f);
  EXPECT_EQ(max_abs_diff(run(0.0f), stack_.color.image), 0.0) << "strength 0 gives the input";
  const Image half = run(0.5f);
  EXPECT_EQ(max_abs_diff(half, with_strength(stack_.color.image, full, 0.5f)), 0.0)
      << "a viewer re-blending a kept result gets exactly what a run at that strength gives";

  // With an ROI only the ROI is blended (outside it the output is the input anyway).
  DenoiseOptions o = options_;
  o.roi = Rect{40, 50, 100, 60};
  o.strength = 0.5f;
  const Image roi_half = denoise(stack_, model_, o);
  o.strength = 1.0f;
  EXPECT_EQ(max_abs_diff(roi_half, with_strength(stack_.color.image, denoise(stack_, model_, o), 0.5f)), 0.0);

  // Streamed, band by band, the same.
  testing::TempDir dir;
  LoadOptions lo;
  lo.reference = kRoom.parent_path() / "reference.exr";
  const AovReader reader({kRoom}, lo);
  o = options_;
  o.strength = 0.5f;
  io::ExrWriteOptions w;
  w.pixel_type = io::PixelType::Float;
  const DenoiseStats stats = denoise_to_exr(reader, model_, o, dir / "out.exr", w);
  EXPECT_EQ(stats.strength, 0.5f);
  EXPECT_EQ(max_abs_diff(testing::read_exr_float(dir / "out.exr"), half), 0.0);
  auto in = OIIO::ImageInput::open((dir / "out.exr").string());
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().get_float_attribute("residue:strength", -1.0f), 0.5f) << "the file says how it was made";
}

TEST_F(StrengthDenoise, OutOfRangeIsRefusedBeforeAnyWork) {
  DenoiseOptions o = options_;
  o.strength = -0.1f;
  int tiles = 0;
  const std::string m = testing::error_message(
      [&] { denoise(stack_, model_, o, [&](const TileEvent&, const Image&) { return ++tiles > 0; }); }, ErrorKind::Usage);
  EXPECT_NE(m.find("outside [0, 1]"), std::string::npos) << m;
  EXPECT_EQ(tiles, 0);
}

// On the bundled room (with its 4096-spp reference) the error falls monotonically from the noisy input to the
// denoised output; the curve for the validation scenes is in docs/MODELS.md.
TEST_F(StrengthDenoise, ErrorFallsAsStrengthRises) {
  ASSERT_TRUE(stack_.reference.has_value());
  const Image full = run(1.0f);
  double last_relmse = 1e30, last_ssim = -1;
  for (float s : {0.0f, 0.25f, 0.5f, 0.75f, 1.0f}) {
    const metrics::Scores m = metrics::compare(with_strength(stack_.color.image, full, s), stack_.reference->image);
    EXPECT_LT(m.relmse, last_relmse) << "strength " << s;
    EXPECT_GT(m.ssim, last_ssim) << "strength " << s;
    last_relmse = m.relmse;
    last_ssim = m.ssim;
  }
}

TEST(StrengthCli, RangeAndProvenance) {
  testing::TempDir dir;
  std::string out;
  EXPECT_EQ(testing::run_cli({"denoise", kRoom.string(), "-m", "tiny", "-o", (dir / "a.exr").string(), "--strength", "1.5"}, &out), 2)
      << out;
  ASSERT_EQ(testing::run_cli({"denoise", kRoom.string(), "-m", "tiny", "-o", (dir / "a.exr").string(), "--strength", "0.25"}, &out), 0)
      << out;
  EXPECT_NE(out.find("strength 0.25"), std::string::npos) << out;
  auto in = OIIO::ImageInput::open((dir / "a.exr").string());
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().get_float_attribute("residue:strength", -1.0f), 0.25f);
}

}  // namespace
}  // namespace residue
