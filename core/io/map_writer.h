// Writing one-channel maps (error maps, SSIM maps) as colour-mapped PNG or as float EXR.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "core/image/colormap.h"
#include "core/image/image.h"

namespace residue::io {

struct MapPngOptions {
  Colormap colormap = Colormap::Viridis;
  ColorScale scale;  // range and linear/log; automatic range when unset
  bool overwrite = false;
};

// Maps each value through the colour scale and colormap (NaN -> the colormap's "invalid" grey) and writes an
// 8-bit RGB PNG atomically.
void write_map_png(const std::filesystem::path& path, const Image& map, const MapPngOptions& options);

// Writes the map as a one-channel float EXR (channel "Y") atomically, values unchanged.
void write_map_exr(const std::filesystem::path& path, const Image& map, bool overwrite);

}  // namespace residue::io
