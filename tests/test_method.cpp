// The method family (core/denoise/method.h) and its registry: a new method is one class and one registry line
// and gets the engine's progress, cancel and worker thread without touching them; progress is one work amount
// over every pass; the filter reports and stops like the networks do.
#include <algorithm>
#include <atomic>
#include <cstring>
#include <vector>

#include <gtest/gtest.h>

#include "core/denoise/bilateral.h"
#include "core/denoise/denoise_job.h"
#include "core/denoise/method_registry.h"
#include "core/denoise/provenance_of.h"
#include "core/nn/model_file.h"
#include "support/test_support.h"

namespace residue {
namespace {

// A method that exists only here: the colour halved, row band by row band. It is the whole of what a new
// method needs (this class, and the register_method() line in the test below).
class HalvingMethod final : public Method {
 public:
  static constexpr int64_t kRows = 8;
  std::string name() const override { return "test-halving"; }
  std::string architecture() const override { return "half the colour"; }
  FeatureSet features() const override { return FeatureSet::ColorOnly; }
  void check_inputs(const AovStack&) const override {}
  int64_t work(int64_t width, int64_t height, const DenoiseOptions& o) const override {
    return region_pixels(width, height, o);
  }
  Image denoise(const AovStack& stack, const DenoiseOptions& o, const TileCallback& on_tile, DenoiseStats& stats,
                WorkCounter& work) const override {
    Image out = stack.color.image;
    const int64_t bands = (stack.height() + kRows - 1) / kRows;
    for (int64_t b = 0; b < bands; ++b) {
      throw_if_cancelled(o.cancel);
      const Rect r{0, b * kRows, stack.width(), std::min(kRows, stack.height() - b * kRows)};
      for (int64_t y = r.y; y < r.y + r.height; ++y)
        for (int64_t x = 0; x < r.width; ++x)
          for (int c = 0; c < out.channels(); ++c) out.at(x, y, c) *= 0.5f;
      work.done += r.area();
      if (on_tile && !on_tile({r, false, b + 1, bands, work.done, work.total, true}, crop(out, r))) throw Cancelled();
    }
    stats.tiles = bands;
    return out;
  }
};

TEST(Method, ANewMethodIsOneClassAndOneRegistryLine) {
  register_method({"test-halving", "halves the colour (a test)", false,
                   [](std::shared_ptr<const nn::Model>) { return std::make_unique<HalvingMethod>(); }});
  ASSERT_TRUE(is_model_free_method("test-halving"));
  nn::ModelRegistry models;
  const AovStack stack = testing::random_stack(20, 30, 7);
  // Resolved by name as -m resolves it, run by the entry point every caller uses.
  const std::unique_ptr<Method> method = resolve_method("test-halving", FeatureSet::Full, models);
  std::vector<TileEvent> events;
  DenoiseStats stats;
  const Image out = denoise(stack, *method, {}, [&](const TileEvent& e, const Image&) {
    events.push_back(e);
    return true;
  }, &stats);
  for (int64_t i = 0; i < static_cast<int64_t>(out.size()); ++i)
    ASSERT_EQ(out.data()[i], stack.color.image.data()[i] * 0.5f) << i;
  ASSERT_EQ(events.size(), 4u);  // 30 rows in bands of 8
  EXPECT_EQ(events.back().work_done, 600);
  EXPECT_EQ(events.back().work_total, 600) << "the entry point asked the method for its work";
  EXPECT_EQ(stats.tiles, 4);

  // On the worker thread, with progress and a cancel, as the viewer runs every method.
  std::atomic<int> seen{0};
  std::atomic<bool> reached{false}, cancelled{false};
  DenoiseJob job(std::make_shared<const AovStack>(stack), make_method(std::string_view("test-halving")), {},
                 [&](const Rect&, const Image&) {
                   if (++seen != 2) return;
                   reached = true;
                   reached.notify_one();
                   cancelled.wait(false);  // the worker holds here until the test has cancelled
                 });
  reached.wait(false);
  job.cancel();
  cancelled = true;
  cancelled.notify_one();
  job.wait();
  EXPECT_EQ(job.status(), DenoiseJob::Status::Cancelled);
  EXPECT_EQ(seen.load(), 2);
  EXPECT_EQ(job.progress().work_done, 2 * 8 * 20);
}

TEST(Method, ModelFreeNamesAreTheRegistrysAndUnknownOnesListThem) {
  EXPECT_TRUE(is_model_free_method("bilateral"));
  EXPECT_FALSE(is_model_free_method("multiscale"));
  EXPECT_FALSE(is_model_free_method("residue")) << "a model kind is not something -m runs without a model";
  const std::string msg = testing::error_message([] { make_method(std::string_view("residue")); }, ErrorKind::Usage);
  EXPECT_NE(msg.find("bilateral"), std::string::npos) << msg;
  const auto families = method_families();
  for (const char* f : {"residue", "oidn", "bilateral"})
    EXPECT_NE(std::find(families.begin(), families.end(), f), families.end()) << f;
}

// The bilateral filter as a method: tile by tile, the same pixels as the filter run at once, progress per
// tile, and a cancel stops it (it used to run to the end whatever the user asked).
TEST(Method, BilateralReportsEveryTileAndStopsOnCancel) {
  const AovStack stack = testing::random_stack(300, 200, 11);
  const std::unique_ptr<Method> method = make_method(std::string_view("bilateral"));
  DenoiseOptions o;
  o.roi = Rect{10, 20, 270, 150};
  std::vector<TileEvent> events;
  const Image out = denoise(stack, *method, o, [&](const TileEvent& e, const Image&) {
    events.push_back(e);
    return true;
  });
  const Image once = cross_bilateral(stack, {}, o.roi);
  ASSERT_EQ(out.size(), once.size());
  EXPECT_EQ(std::memcmp(out.data(), once.data(), out.size() * sizeof(float)), 0) << "bit-identical to the whole filter";
  ASSERT_EQ(events.size(), 6u);  // 270 x 150 in tiles of 128: 3 x 2
  for (size_t i = 1; i < events.size(); ++i) {
    EXPECT_GT(events[i].work_done, events[i - 1].work_done);
  }
  EXPECT_EQ(events.back().work_done, events.back().work_total);

  CancelToken cancel;
  o.cancel = &cancel;
  int calls = 0;
  EXPECT_THROW(denoise(stack, *method, o, [&](const TileEvent&, const Image&) {
    ++calls;
    cancel.request();
    return true;
  }), Cancelled);
  EXPECT_EQ(calls, 1) << "stops before the next tile";
}

// OIDN's final-frame mode runs three networks: the albedo's and the normal's prefilters on the whole image, then
// the colour's. Progress is one amount over the three, so the bar moves once from 0 to the whole; the
// prefilters' tiles say that their pixels are not the result (a viewer must not draw an albedo as the colour).
TEST(Method, PrefilteredRunReportsOneWorkAmountOverEveryPass) {
  const std::filesystem::path file = testing::oidn_dir() / "rt_hdr_calb_cnrm_large.tza";
  auto model = std::make_shared<const nn::Model>(nn::load_model(file));
  ASSERT_TRUE(model->albedo_prefilter && model->normal_prefilter);
  const std::unique_ptr<Method> method = make_method(model);
  const AovStack stack = testing::random_stack(48, 40, 3);
  DenoiseOptions o;
  o.tile = 32;
  o.roi = Rect{8, 8, 40, 24};  // two tiles of 32 on the image grid
  std::vector<TileEvent> events;
  denoise(stack, *method, o, [&](const TileEvent& e, const Image&) {
    events.push_back(e);
    return true;
  });
  ASSERT_FALSE(events.empty());
  const int64_t total = method->work(48, 40, o);
  const auto first_result = std::find_if(events.begin(), events.end(), [](const TileEvent& e) { return e.result; });
  ASSERT_NE(first_result, events.begin()) << "the prefilters ran first and reported";
  ASSERT_NE(first_result, events.end());
  EXPECT_TRUE(std::all_of(first_result, events.end(), [](const TileEvent& e) { return e.result; }));
  for (size_t i = 0; i < events.size(); ++i) {
    EXPECT_EQ(events[i].work_total, total) << i;
    if (i > 0) {
      EXPECT_GT(events[i].work_done, events[i - 1].work_done) << i;
    }
  }
  EXPECT_EQ(events.back().work_done, total);
  // The prefilters cover the whole image, the colour only the region: most of the work is theirs.
  EXPECT_LT(first_result->work_done, total);
  EXPECT_GT(std::prev(first_result)->work_done, total / 2);
}

// One provenance for every writer: what ran, by name, with its backend, post-steps and time.
TEST(Method, ProvenanceSaysWhatRan) {
  const AovStack stack = testing::random_stack(40, 40, 5);
  const std::unique_ptr<Method> filter = make_method(std::string_view("bilateral"));
  DenoiseOptions o;
  o.strength = 0.75f;
  DenoiseStats stats;
  denoise(stack, *filter, o, {}, &stats);
  const io::Provenance p = provenance_of(*filter, stats);
  EXPECT_EQ(p.model, "bilateral");
  EXPECT_EQ(p.architecture, "cross-bilateral filter");
  EXPECT_EQ(p.backend, "cross-bilateral (core)");
  EXPECT_EQ(p.strength, 0.75f);
  EXPECT_EQ(p.energy_correction, false) << "the filter has no post-steps";
  ASSERT_TRUE(p.seconds.has_value());
  EXPECT_GT(*p.seconds, 0.0f);
  // A streamed EXR's header is written before the time is known: no time rather than a zero.
  stats.seconds = 0;
  EXPECT_FALSE(run_provenance(stats).seconds.has_value());
}

}  // namespace
}  // namespace residue
