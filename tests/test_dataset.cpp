// Data set listing and the train/validation cut (index.json of tools/datagen, or the last scenes by name).
#include <cmath>
#include <fstream>
#include <limits>

#include <gtest/gtest.h>

#include "core/aov/aov_loader.h"
#include "core/aov/dataset.h"
#include "core/util/error.h"
#include "support/test_support.h"

namespace residue {
namespace {

void make_scene(const std::filesystem::path& dir, bool complete = true) {
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "noisy_a.exr") << "x";
  if (complete) std::ofstream(dir / "reference.exr") << "x";
}

std::vector<std::string> names(const std::vector<std::filesystem::path>& v) {
  std::vector<std::string> out;
  for (const auto& p : v) out.push_back(p.filename().string());
  return out;
}

TEST(Dataset, ListsCompleteScenesSorted) {
  testing::TempDir dir;
  make_scene(dir / "s2");
  make_scene(dir / "s1");
  make_scene(dir / "s3", /*complete=*/false);  // no reference: not a scene
  std::filesystem::create_directories(dir / ".tmp-s4/scene");
  EXPECT_EQ(names(list_dataset_scenes(dir.path())), (std::vector<std::string>{"s1", "s2"}));
  EXPECT_THROW(list_dataset_scenes(dir / "missing"), Error);
}

TEST(Dataset, SplitFollowsTheIndex) {
  testing::TempDir dir;
  for (const char* s : {"s1000", "s1001", "s1010", "s1021"}) make_scene(dir / s);
  // s1021 finished after the index was written; s1099 is listed but gone: both left out.
  std::ofstream(dir / "index.json") << R"({"scenes": [
      {"folder": "s1000", "split": "train"}, {"folder": "s1001", "split": "train"},
      {"folder": "s1010", "split": "validation"}, {"folder": "s1099", "split": "validation"}]})";
  const DatasetSplit split = split_dataset(dir.path(), 6);
  EXPECT_TRUE(split.from_index);
  EXPECT_EQ(names(split.train), (std::vector<std::string>{"s1000", "s1001"}));
  EXPECT_EQ(names(split.validation), (std::vector<std::string>{"s1010"}));
}

TEST(Dataset, SplitWithoutIndexHoldsOutTheLastScenes) {
  testing::TempDir dir;
  for (const char* s : {"s1", "s2", "s3", "s4", "s5"}) make_scene(dir / s);
  DatasetSplit split = split_dataset(dir.path(), 2);
  EXPECT_FALSE(split.from_index);
  EXPECT_EQ(names(split.train), (std::vector<std::string>{"s1", "s2", "s3"}));
  EXPECT_EQ(names(split.validation), (std::vector<std::string>{"s4", "s5"}));
  split = split_dataset(dir.path(), 100);  // never more than half
  EXPECT_EQ(split.validation.size(), 2u);
}

TEST(Dataset, BrokenIndexNamesTheFile) {
  testing::TempDir dir;
  make_scene(dir / "s1");
  std::ofstream(dir / "index.json") << R"({"scenes": [{"folder": "s1"}]})";
  try {
    split_dataset(dir.path(), 1);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("index.json"), std::string::npos) << e.what();
    EXPECT_EQ(e.kind(), ErrorKind::Input);
  }
}

}  // namespace
}  // namespace residue

namespace residue {
namespace {

TEST(Dataset, VarianceFromHalvesIsHalfTheSquaredDifference) {
  Image a(2, 1, 3, 1.0f), b(2, 1, 3, 1.0f);
  a.at(0, 0, 0) = 3.0f;  // d = 2 -> 2
  b.at(1, 0, 2) = 0.5f;  // d = 0.5 -> 0.125
  a.at(1, 0, 1) = std::numeric_limits<float>::quiet_NaN();
  const Image v = variance_from_halves(a, b);
  EXPECT_FLOAT_EQ(v.at(0, 0, 0), 2.0f);
  EXPECT_FLOAT_EQ(v.at(0, 0, 1), 0.0f);
  EXPECT_FLOAT_EQ(v.at(1, 0, 2), 0.125f);
  EXPECT_EQ(v.at(1, 0, 1), 0.0f) << "non-finite difference -> 0";
  EXPECT_THROW(variance_from_halves(a, Image(3, 1, 3)), Error);
}

TEST(Dataset, SceneGetsTheVarianceOfItsHalves) {
  const auto scene = testing::shared_dataset("cycles-starter/s100");
  RESIDUE_REQUIRE_SHARED(scene);
  const AovStack s = load_dataset_scene(scene);
  ASSERT_TRUE(s.variance && s.reference);
  // Independently: read noisy_b and compare one pixel.
  LoadOptions o;
  o.load_reference = false;
  const AovStack b = load_aov_stack({scene / "noisy_b.exr"}, o);
  const double d = double(s.color.image.at(100, 120, 1)) - double(b.color.image.at(100, 120, 1));
  EXPECT_NEAR(s.variance->image.at(100, 120, 1), 0.5 * d * d, 1e-6 * (1 + d * d));
  // Its mean relative to the colour's squared mean is the scene's noise: relMSE of a half against the other is
  // about 2x the per-half variance; here simply check it is positive and finite.
  double sum = 0;
  for (size_t i = 0; i < s.variance->image.size(); ++i) sum += s.variance->image.data()[i];
  EXPECT_GT(sum, 0.0);
  EXPECT_TRUE(std::isfinite(sum));
}

}  // namespace
}  // namespace residue
