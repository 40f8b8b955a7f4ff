// Colormaps for one-channel maps: the perceptually uniform viridis, inferno, magma (matplotlib) and turbo
// (Google), and a diverging one for signed values, bluered (ColorBrewer's RdBu reversed, as matplotlib's RdBu_r:
// blue below the middle, white at it, red above). One place for this display maths, so the viewer's heatmaps and
// exported PNGs agree.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "core/image/image.h"

namespace residue {

enum class Colormap { Viridis, Inferno, Magma, Turbo, BlueRed };
const char* to_string(Colormap map);
std::optional<Colormap> colormap_from_string(const std::string& name);

// How values map to [0, 1] before the colormap: linear or log10 between lo and hi (clamped). NaN has no colour
// (kInvalidColor), +-Inf clamp to the ends; on a log scale values <= 0 map to 0. With lo == hi, values below map
// to 0, equal to 0.5, above to 1. Automatic bounds ignore NaN and Inf; an automatic log lo is the smallest
// positive value (hi * 1e-6 when there is none); nothing finite at all gives [0, 1] ([1e-6, 1] for log).
struct ColorScale {
  bool log = false;
  std::optional<double> lo;  // automatic (finite min; for log, smallest positive) when unset
  std::optional<double> hi;  // automatic (finite max) when unset
  // Signed values: automatic bounds are -m and m, m the largest finite |value|, so that 0 sits in the middle of a
  // diverging colormap (an explicit bound gives the other its negative). Not with log.
  bool symmetric = false;
};

// Resolved bounds for `scale` over `map` (fills in automatic bounds; an automatic bound beyond an explicit one
// collapses onto it). Throws residue::Error(Usage) for lo > hi, non-finite bounds, or log with a bound <= 0.
std::pair<double, double> resolve_range(const Image& map, const ColorScale& scale);

// t in [0, 1] -> sRGB-encoded 8-bit colour, interpolating linearly between the 256 table entries
// (colormap_tables.inc, generated from matplotlib by tools/dev/gen_colormaps.py) and rounding. Values outside (and
// NaN) are clamped.
std::array<uint8_t, 3> colormap_lookup(Colormap map, double t);

// The colour used for NaN (excluded) pixels.
inline constexpr std::array<uint8_t, 3> kInvalidColor{128, 128, 128};

// A one-channel map -> RGB image with values in [0, 1] (sRGB encoded), ready for 8-bit output: each value is
// exactly k / 255 with k the byte colormap_lookup gives. Throws residue::Error(Usage) unless one channel.
Image apply_colormap(const Image& map, Colormap colormap, const ColorScale& scale);

}  // namespace residue
