// Colormaps for one-channel maps: the perceptually uniform viridis, inferno, magma (matplotlib) and turbo
// (Google). One place for this display maths, so the viewer's heatmaps and exported PNGs agree.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "core/image/image.h"

namespace residue {

enum class Colormap { Viridis, Inferno, Magma, Turbo };
const char* to_string(Colormap map);
std::optional<Colormap> colormap_from_string(const std::string& name);

// How values map to [0, 1] before the colormap: linear or log10 between lo and hi (clamped).
struct ColorScale {
  bool log = false;
  std::optional<double> lo;  // automatic (finite min; for log, smallest positive) when unset
  std::optional<double> hi;  // automatic (finite max) when unset
};

// Resolved bounds for `scale` over `map` (fills in automatic bounds).
std::pair<double, double> resolve_range(const Image& map, const ColorScale& scale);

// t in [0, 1] -> sRGB-encoded 8-bit colour. Values outside are clamped.
std::array<uint8_t, 3> colormap_lookup(Colormap map, double t);

// The colour used for NaN (excluded) pixels.
inline constexpr std::array<uint8_t, 3> kInvalidColor{128, 128, 128};

// A one-channel map -> RGB image with values in [0, 1] (sRGB encoded), ready for 8-bit output.
Image apply_colormap(const Image& map, Colormap colormap, const ColorScale& scale);

}  // namespace residue
