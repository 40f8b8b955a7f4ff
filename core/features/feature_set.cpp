#include "core/features/feature_set.h"

#include <algorithm>

namespace residue {

int feature_channels(FeatureSet set) { return static_cast<int>(feature_planes(set).size()); }

std::vector<std::string> feature_planes(FeatureSet set) {
  std::vector<std::string> planes = {"color.r", "color.g", "color.b"};
  if (set == FeatureSet::ColorOnly) return planes;
  if (set == FeatureSet::Full || set == FeatureSet::FullVariance) planes.push_back("depth");
  for (const char* p : {"normal.x", "normal.y", "albedo.r", "albedo.g", "albedo.b"}) planes.push_back(p);
  if (set == FeatureSet::FullVariance) planes.push_back("noise");
  return planes;
}

int feature_plane(FeatureSet set, const std::string& name) {
  const std::vector<std::string> planes = feature_planes(set);
  const auto it = std::find(planes.begin(), planes.end(), name);
  return it == planes.end() ? -1 : static_cast<int>(it - planes.begin());
}

int first_plane(FeatureSet set, AovRole role) {
  switch (role) {
    case AovRole::Color: return feature_plane(set, "color.r");
    case AovRole::Depth: return feature_plane(set, "depth");
    case AovRole::Normal: return feature_plane(set, "normal.x");
    case AovRole::Albedo: return feature_plane(set, "albedo.r");
    case AovRole::Variance: return feature_plane(set, "noise");
    case AovRole::Reference:
    case AovRole::Motion: return -1;  // the reference is never an input; no feature set reads motion yet
  }
  return -1;
}

const char* to_string(FeatureSet set) {
  switch (set) {
    case FeatureSet::Full: return "full";
    case FeatureSet::ColorAlbedoNormal: return "color+albedo+normal";
    case FeatureSet::ColorOnly: return "color";
    case FeatureSet::FullVariance: return "full+variance";
  }
  return "?";
}

std::optional<FeatureSet> feature_set_from_string(const std::string& name) {
  for (FeatureSet s : {FeatureSet::Full, FeatureSet::ColorAlbedoNormal, FeatureSet::ColorOnly, FeatureSet::FullVariance})
    if (name == to_string(s)) return s;
  return std::nullopt;
}

}  // namespace residue
