// Which AOVs a model reads, and in which order its input planes come.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "core/aov/aov_stack.h"

namespace residue {

enum class FeatureSet {
  Full,               // 9: colour (3), depth (1), view-space normal x,y (2), albedo (3) — the paper's input
  ColorAlbedoNormal,  // 8: colour (3), normal x,y (2), albedo (3) — for renders without depth
  ColorOnly,          // 3: colour — for beauty-only renders
  FullVariance,       // 10: full + the colour's noise level (per-pixel variance of the estimate) — a variant
                      //     for renderers that write variance (Tungsten) or two independent halves (Cycles data)
};

int feature_channels(FeatureSet set);
// The input planes by name, in the network's order (core/features/features.h says what each holds):
// "color.r", "color.g", "color.b", "depth", "normal.x", "normal.y", "albedo.r", "albedo.g", "albedo.b", "noise".
std::vector<std::string> feature_planes(FeatureSet set);
// The index of a named plane in the set's order; -1 when the set has none.
int feature_plane(FeatureSet set, const std::string& name);
// The index of the first plane `role` feeds (colour r, depth, normal x, albedo r, the variance's noise level);
// -1 when the set does not read it.
int first_plane(FeatureSet set, AovRole role);
const char* to_string(FeatureSet set);  // "full", "color+albedo+normal", "color"
std::optional<FeatureSet> feature_set_from_string(const std::string& name);

}  // namespace residue
