// Writing images as OpenEXR: half or float, a chosen compression, the source's metadata kept, and
// residue:* attributes that say how the file was made.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <OpenImageIO/paramlist.h>

#include "core/image/image.h"

namespace residue::io {

enum class PixelType { Half, Float };

struct ExrWriteOptions {
  PixelType pixel_type = PixelType::Half;
  std::string compression = "zip";      // any OpenEXR compression OIIO knows: none, zip, zips, piz, dwaa, ...
  std::vector<std::string> channel_names;  // defaults: R,G,B(,A) / Y for one channel / C0.. otherwise
  OIIO::ParamValueList metadata;         // header attributes to keep (from the source), written first
  OIIO::ParamValueList residue_attributes;  // residue:model, residue:backend, ... (added after metadata)
  Rect data_window{};                    // where the pixels sit in the display window (x, y origin)
  int64_t display_width = 0;             // display window; 0 = same as the image
  int64_t display_height = 0;
  bool overwrite = false;
};

// Writes `image` atomically (atomic_file.h). Throws residue::Error(Output) on failure or existing file.
void write_exr(const std::filesystem::path& path, const Image& image, const ExrWriteOptions& options);

}  // namespace residue::io
