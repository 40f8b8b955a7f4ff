#include "core/features/feature_set.h"

namespace residue {

int feature_channels(FeatureSet set) {
  switch (set) {
    case FeatureSet::Full: return 9;
    case FeatureSet::ColorAlbedoNormal: return 8;
    case FeatureSet::ColorOnly: return 3;
    case FeatureSet::FullVariance: return 10;
  }
  return 0;
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
