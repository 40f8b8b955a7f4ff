#include "core/image/colormap.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>

#include "core/util/error.h"

namespace residue {

namespace {

#include "core/image/colormap_tables.inc"

constexpr std::array<const char*, 5> kNames = {"viridis", "inferno", "magma", "turbo", "bluered"};
static_assert(sizeof(kColormapTables) / sizeof(kColormapTables[0]) == kNames.size(),
              "one table per Colormap, in enum order");

// Linear interpolation between the 256 entries; t is clamped to [0, 1].
std::array<double, 3> interpolate(Colormap map, double t) {
  const auto& table = kColormapTables[static_cast<int>(map)];
  t = std::clamp(std::isnan(t) ? 0.0 : t, 0.0, 1.0);
  const double x = t * (kColormapEntries - 1);
  const int i = std::min(static_cast<int>(x), kColormapEntries - 2);
  const double f = x - i;
  std::array<double, 3> rgb{};
  for (int c = 0; c < 3; ++c) rgb[c] = table[i][c] * (1.0 - f) + table[i + 1][c] * f;
  return rgb;
}

uint8_t to_8bit(double v) { return static_cast<uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0)); }

// Finite extremes of a map: the smallest and largest finite values, and the smallest positive one.
struct Extremes {
  double min = std::numeric_limits<double>::infinity();
  double max = -std::numeric_limits<double>::infinity();
  double min_positive = std::numeric_limits<double>::infinity();
  void add(double v) {
    if (!std::isfinite(v)) return;
    min = std::min(min, v);
    max = std::max(max, v);
    if (v > 0) min_positive = std::min(min_positive, v);
  }
  Extremes& merge(const Extremes& o) {
    min = std::min(min, o.min);
    max = std::max(max, o.max);
    min_positive = std::min(min_positive, o.min_positive);
    return *this;
  }
};

Extremes find_extremes(const Image& map) {
  return tbb::parallel_reduce(
      tbb::blocked_range<int64_t>(0, map.height()), Extremes{},
      [&](const tbb::blocked_range<int64_t>& rows, Extremes acc) {
        for (int64_t y = rows.begin(); y != rows.end(); ++y)
          for (int64_t x = 0; x < map.width(); ++x) acc.add(map.at(x, y, 0));
        return acc;
      },
      [](Extremes a, const Extremes& b) { return a.merge(b); });
}

std::string number(double v) {
  std::array<char, 32> buf{};
  return {buf.data(), std::to_chars(buf.data(), buf.data() + buf.size(), v).ptr};
}

// Value -> [0, 1] with resolved bounds; NaN stays NaN. With lo == hi: below 0, at the value 0.5, above 1.
double normalize(double v, double lo, double hi, bool log) {
  if (std::isnan(v)) return v;
  if (log) {
    if (v <= 0) return 0.0;
    v = std::log10(v);
    lo = std::log10(lo);
    hi = std::log10(hi);
  }
  if (!(hi > lo)) return v < lo ? 0.0 : v > hi ? 1.0 : 0.5;
  return std::clamp((v - lo) / (hi - lo), 0.0, 1.0);
}

}  // namespace

const char* to_string(Colormap map) { return kNames[static_cast<size_t>(map)]; }

std::optional<Colormap> colormap_from_string(const std::string& name) {
  std::string lower = name;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (size_t i = 0; i < kNames.size(); ++i)
    if (lower == kNames[i]) return static_cast<Colormap>(i);
  return std::nullopt;
}

std::pair<double, double> resolve_range(const Image& map, const ColorScale& scale) {
  if (scale.lo && scale.hi && *scale.lo > *scale.hi)
    throw Error(ErrorKind::Usage, "colour scale: low bound " + number(*scale.lo) +
                                      " is above the high bound " + number(*scale.hi));
  if (scale.log && ((scale.lo && !(*scale.lo > 0)) || (scale.hi && !(*scale.hi > 0))))
    throw Error(ErrorKind::Usage, "a log colour scale needs positive bounds");
  if ((scale.lo && !std::isfinite(*scale.lo)) || (scale.hi && !std::isfinite(*scale.hi)))
    throw Error(ErrorKind::Usage, "colour scale bounds must be finite numbers");

  if (scale.log && scale.symmetric) throw Error(ErrorKind::Usage, "a symmetric colour scale cannot be a log one");
  const Extremes e = (scale.lo && scale.hi) ? Extremes{} : find_extremes(map);
  double hi = 0, lo = 0;
  if (scale.symmetric) {
    const bool any = e.min <= e.max;
    const double m = scale.hi ? std::abs(*scale.hi) : scale.lo ? std::abs(*scale.lo)
                     : any   ? std::max(std::abs(e.min), std::abs(e.max))
                             : 1.0;
    lo = scale.lo ? *scale.lo : -m;
    hi = scale.hi ? *scale.hi : m;
  } else if (scale.log) {
    // No positive value at all: an arbitrary decade range that puts everything at the bottom.
    hi = scale.hi ? *scale.hi : (e.max > 0 ? e.max : 1.0);
    lo = scale.lo ? *scale.lo : (std::isfinite(e.min_positive) ? e.min_positive : hi * 1e-6);
  } else {
    const bool any = e.min <= e.max;  // some finite value
    hi = scale.hi ? *scale.hi : (any ? e.max : 1.0);
    lo = scale.lo ? *scale.lo : (any ? e.min : 0.0);
  }
  // An automatic bound on the wrong side of an explicit one collapses onto it.
  if (lo > hi) {
    if (scale.lo)
      hi = lo;
    else
      lo = hi;
  }
  return {lo, hi};
}

std::array<uint8_t, 3> colormap_lookup(Colormap map, double t) {
  const auto rgb = interpolate(map, t);
  return {to_8bit(rgb[0]), to_8bit(rgb[1]), to_8bit(rgb[2])};
}

Image apply_colormap(const Image& map, Colormap colormap, const ColorScale& scale) {
  if (map.channels() != 1)
    throw Error(ErrorKind::Usage, "a colormap applies to a one-channel map, not " +
                                      std::to_string(map.channels()) + " channels");
  // Named variables, not a structured binding: the lambda below captures them, which clang before 16 rejects.
  const std::pair<double, double> range = resolve_range(map, scale);
  const double lo = range.first, hi = range.second;
  Image out(map.width(), map.height(), 3);
  tbb::parallel_for(tbb::blocked_range<int64_t>(0, map.height()),
                    [&](const tbb::blocked_range<int64_t>& rows) {
                      for (int64_t y = rows.begin(); y != rows.end(); ++y)
                        for (int64_t x = 0; x < map.width(); ++x) {
                          const double t = normalize(map.at(x, y, 0), lo, hi, scale.log);
                          const auto rgb = std::isnan(t) ? kInvalidColor : colormap_lookup(colormap, t);
                          // Exactly k/255, so that any 8-bit conversion gives the bytes colormap_lookup
                          // gives.
                          for (int c = 0; c < 3; ++c) out.at(x, y, c) = static_cast<float>(rgb[c]) / 255.0f;
                        }
                    });
  return out;
}

}  // namespace residue
