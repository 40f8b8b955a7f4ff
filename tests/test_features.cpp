// Feature sets: which planes a model reads, found by the AOV that feeds them.
#include <gtest/gtest.h>

#include "core/features/feature_set.h"

namespace residue {
namespace {

TEST(FeatureSets, PlanesAreFoundByTheirRole) {
  // full: colour (0-2), depth (3), normal x,y (4-5), albedo (6-8)
  EXPECT_EQ(first_plane(FeatureSet::Full, AovRole::Color), 0);
  EXPECT_EQ(first_plane(FeatureSet::Full, AovRole::Depth), 3);
  EXPECT_EQ(first_plane(FeatureSet::Full, AovRole::Normal), 4);
  EXPECT_EQ(first_plane(FeatureSet::Full, AovRole::Albedo), 6);
  EXPECT_EQ(first_plane(FeatureSet::Full, AovRole::Variance), -1);
  // without depth everything after the colour moves up one
  EXPECT_EQ(first_plane(FeatureSet::ColorAlbedoNormal, AovRole::Depth), -1);
  EXPECT_EQ(first_plane(FeatureSet::ColorAlbedoNormal, AovRole::Normal), 3);
  EXPECT_EQ(first_plane(FeatureSet::ColorAlbedoNormal, AovRole::Albedo), 5);
  EXPECT_EQ(first_plane(FeatureSet::FullVariance, AovRole::Variance), 9);
  EXPECT_EQ(first_plane(FeatureSet::ColorOnly, AovRole::Normal), -1);
  EXPECT_EQ(first_plane(FeatureSet::Full, AovRole::Reference), -1) << "never an input";
  EXPECT_EQ(first_plane(FeatureSet::Full, AovRole::Motion), -1) << "no feature set reads motion yet";
  EXPECT_EQ(feature_channels(FeatureSet::FullVariance), 10);
}

}  // namespace
}  // namespace residue
