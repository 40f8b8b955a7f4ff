// The temporal method's inputs and model (issue 51): a shot's neighbouring frames warped to frame t
// (core/temporal/frame_window.h), one and two frames away; the frames a shot lacks reported and read as not
// valid; the neighbours' feature planes; a temporal model whose neighbour weights are zero denoising exactly as
// the still model it was made from, and the neighbours reaching the network when they are not.
#include <cmath>
#include <map>

#include <gtest/gtest.h>

#include "core/aov/shot_dataset.h"
#include "core/denoise/method_registry.h"
#include "core/features/features.h"
#include "core/nn/model_file.h"
#include "core/nn/model_registry.h"
#include "core/temporal/frame_window.h"
#include "support/test_support.h"

namespace residue {
namespace {

namespace fs = std::filesystem;

constexpr int64_t kW = 24, kH = 10;

// Frame `index` of a shot whose camera pans 2 px a frame to the right: frame i shows `strip` from column 2 i
// onwards, so a surface at column x of frame i is at x + 2 in frame i - 1 and at x - 2 in frame i + 1. Depth and
// normals are constant (one wall).
AovStack pan_frame(const Image& strip, int index) {
  AovStack s = testing::random_stack(kW, kH, 5);
  for (int64_t y = 0; y < kH; ++y)
    for (int64_t x = 0; x < kW; ++x) {
      for (int c = 0; c < 3; ++c) s.color.image.at(x, y, c) = strip.at(x + 2 * (index + 2), y, c);
      s.depth->image.at(x, y) = 5.0f;
      s.normal->image.at(x, y, 0) = 0, s.normal->image.at(x, y, 1) = 0, s.normal->image.at(x, y, 2) = 1;
    }
  s.color.source.file = "pan." + std::to_string(index) + ".exr";
  Aov motion;
  motion.image = Image(kW, kH, 4);
  for (int64_t y = 0; y < kH; ++y)
    for (int64_t x = 0; x < kW; ++x) motion.image.at(x, y, 0) = 2.0f, motion.image.at(x, y, 2) = -2.0f;
  s.motion = motion;
  return s;
}

struct Pan {
  Image strip = testing::random_image(kW + 12, kH, 3, 11, 0.0f, 3.0f);
  std::map<int, AovStack> frames;  // by offset from frame t (0)
  explicit Pan(int lo = -2, int hi = 2) {
    for (int d = lo; d <= hi; ++d) frames.emplace(d, pan_frame(strip, d));
  }
  ShotFrames shot() const {
    return [this](int d) -> const AovStack* {
      const auto it = frames.find(d);
      return it == frames.end() ? nullptr : &it->second;
    };
  }
};

TEST(TemporalInputs, NeighboursOneAndTwoFramesAwayLandOnFrameT) {
  Pan pan;
  AovStack t = pan.frames.at(0);
  EXPECT_TRUE(attach_neighbours(t, 2, pan.shot()).empty());
  ASSERT_EQ(t.neighbours.size(), 4u);
  for (int d : {-2, -1, 1, 2}) {
    const WarpedNeighbour* n = t.neighbour(d);
    ASSERT_NE(n, nullptr) << d;
    int64_t valid = 0;
    for (int64_t y = 0; y < kH; ++y)
      for (int64_t x = 0; x < kW; ++x) {
        // The surface at x came from x + 2 |d| in the frames before and goes to x - 2 |d| in the frames after.
        const int64_t source = x - 2 * d;
        const bool inside = source >= 0 && source < kW;
        ASSERT_EQ(n->valid.at(x, y), inside ? 1.0f : 0.0f) << "offset " << d << " at " << x << "," << y;
        valid += inside;
        for (int c = 0; c < 3; ++c)  // the same surface; this frame's own colour where not valid
          ASSERT_EQ(n->color.at(x, y, c), t.color.image.at(x, y, c)) << "offset " << d << " at " << x << "," << y;
      }
    EXPECT_EQ(valid, (kW - 2 * std::abs(d)) * kH) << "offset " << d;
  }
}

TEST(TemporalInputs, FramesTheShotLacksAreReportedAndReadAsNotValid) {
  Pan pan(0, 1);  // the shot's first frame, and one after it
  AovStack t = pan.frames.at(0);
  EXPECT_EQ(attach_neighbours(t, 2, pan.shot()), (std::vector<int>{-2, -1, 2}));
  ASSERT_EQ(t.neighbours.size(), 1u);
  EXPECT_EQ(t.neighbours.front().offset, 1);

  // The planes: the neighbour's log colour and its validity; a missing one reads as this frame's colour, not valid.
  FeatureStats stats = compute_feature_stats(t);
  stats.temporal = 1;
  Image planes;
  make_features(t, FeatureSet::Full, stats, {0, 0, kW, kH}, planes);
  ASSERT_EQ(planes.channels(), 9 + 8);
  for (int64_t y = 0; y < kH; ++y)
    for (int64_t x = 0; x < kW; ++x) {
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(planes.at(x, y, 9 + c), planes.at(x, y, c)) << "t-1, missing";
        EXPECT_EQ(planes.at(x, y, 13 + c), compress_color(t.neighbours.front().color.at(x, y, c))) << "t+1";
      }
      EXPECT_EQ(planes.at(x, y, 12), 0.0f);
      EXPECT_EQ(planes.at(x, y, 16), x >= 2 ? 1.0f : 0.0f);
    }
}

TEST(TemporalInputs, AFrameWithoutMotionIsRefusedNamingIt) {
  Pan pan;
  AovStack t = pan.frames.at(0);
  t.motion.reset();
  EXPECT_NE(testing::error_message([&] { attach_neighbours(t, 1, pan.shot()); }, ErrorKind::Input).find("'pan.0.exr' has no motion vectors"),
            std::string::npos);
  // Two frames away, the frame between is warped through: its motion is needed too.
  pan.frames.at(-1).motion.reset();
  AovStack u = pan.frames.at(0);
  EXPECT_NE(testing::error_message([&] { attach_neighbours(u, 2, pan.shot()); }, ErrorKind::Input).find("'pan.-1.exr' has no motion"),
            std::string::npos);
}

// multiscale made temporal: the head reads 8 more planes, with zero weights.
nn::Model temporal_from(const nn::Model& still, float neighbour_weight) {
  nn::Network n = still.network;
  n.arch.temporal = 1;
  nn::Conv3x3 head = n.head;
  head.in = n.arch.in_channels();
  head.weight.assign(static_cast<size_t>(head.out * head.in * 9), 0.0f);
  for (int o = 0; o < head.out; ++o)
    for (int i = 0; i < head.in; ++i)
      for (int k = 0; k < 9; ++k)
        head.weight[static_cast<size_t>((o * head.in + i) * 9 + k)] =
            i < n.head.in ? n.head.weight[static_cast<size_t>((o * n.head.in + i) * 9 + k)] : neighbour_weight;
  n.head = head;
  nn::Model m = nn::model_from_network(n, "test-temporal");
  return m;
}

TEST(TemporalModel, ZeroNeighbourWeightsDenoiseAsTheStillModel) {
  const auto still = std::make_shared<const nn::Model>(nn::load_model(nn::find_model_for("multiscale", FeatureSet::Full)));
  const auto temporal = std::make_shared<const nn::Model>(temporal_from(*still, 0.0f));
  const std::unique_ptr<Method> method = make_method(temporal);
  EXPECT_EQ(method->frame_radius(), 1);
  EXPECT_FALSE(method->streams()) << "the neighbours are whole images in memory";
  EXPECT_NE(method->architecture().find("temporal 1"), std::string::npos) << method->architecture();
  EXPECT_EQ(make_method(still)->frame_radius(), 0);

  Pan pan;
  AovStack t = pan.frames.at(0);
  attach_neighbours(t, 1, pan.shot());
  DenoiseOptions o;
  o.skip_empty_tiles = false;
  o.variance_blend = false;
  const Image a = denoise(t, *method, o), b = denoise(t, *make_method(still), o);
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i)
    worst = std::max(worst, std::abs(double{a.data()[i]} - b.data()[i]) / (std::abs(double{b.data()[i]}) + 1e-3));
  EXPECT_LT(worst, 1e-5) << "the neighbours' planes add exact zeros";

  // With weight on them, the neighbours reach the network: another t+1 changes frame t's result.
  const std::unique_ptr<Method> reading = make_method(std::make_shared<const nn::Model>(temporal_from(*still, 0.01f)));
  const Image c = denoise(t, *reading, o);
  AovStack dark = t;
  for (WarpedNeighbour& n : dark.neighbours)
    if (n.offset == 1)
      for (size_t i = 0; i < n.color.size(); ++i) n.color.data()[i] *= 0.25f;
  const Image d = denoise(dark, *reading, o);
  double changed = 0;
  for (size_t i = 0; i < c.size(); ++i) changed = std::max(changed, double{std::abs(c.data()[i] - d.data()[i])});
  EXPECT_GT(changed, 1e-4);
}

TEST(TemporalModel, TheModelFileSaysItsRadius) {
  const nn::Model still = nn::load_model(nn::find_model_for("multiscale", FeatureSet::Full));
  const nn::Model temporal = temporal_from(still, 0.0f);
  const testing::TempDir dir;
  const fs::path file = dir.path() / "t.safetensors";
  nn::write_safetensors(file, nn::to_safetensors(temporal.network, {{"name", "t"}}), false);
  const nn::Model back = nn::load_model(file);
  EXPECT_EQ(back.network.arch.temporal, 1);
  EXPECT_EQ(back.network.arch.in_channels(), 17);
  const std::vector<std::string> planes = nn::input_planes(back.network.arch);
  ASSERT_EQ(planes.size(), 17u);
  EXPECT_EQ(planes[9], "t-1.color.r");
  EXPECT_EQ(planes[12], "t-1.valid");
  EXPECT_EQ(planes[16], "t+1.valid");
}

}  // namespace
}  // namespace residue
