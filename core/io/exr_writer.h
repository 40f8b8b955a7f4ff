// Writing images as OpenEXR: half or float, a chosen compression, the source's metadata kept, and
// residue:* attributes that say how the file was made.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <OpenImageIO/paramlist.h>

#include "core/image/image.h"

namespace residue::io {

enum class PixelType { Half, Float };

struct ExrWriteOptions {
  PixelType pixel_type = PixelType::Half;
  // none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa, dwab; optionally with a level: "zip:9", "dwaa:45".
  std::string compression = "zip";
  std::vector<std::string> channel_names;  // defaults: R,G,B(,A) / Y for one channel / C0.. otherwise
  // Header attributes to keep (from the source), written first. Those that describe the source's layout or
  // encoding (compression, windows, tiles, chunkCount, lineOrder, part name/type, oiio:*, ...) and residue:* of an
  // earlier run are skipped.
  OIIO::ParamValueList metadata;
  // residue:model, residue:backend, ... (added after metadata, replacing same names). Strings, floats, ints and
  // doubles are written as such; other types as their text.
  OIIO::ParamValueList residue_attributes;
  Rect data_window{};                    // where the pixels sit in the display window (x, y origin); a
                                         // non-zero width/height must equal the image's
  int64_t display_width = 0;             // display window, origin (0, 0); 0 = same as the image
  int64_t display_height = 0;
  bool overwrite = false;
};

// The compressions write_exr accepts (none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa, dwab), for menus and
// help texts.
std::vector<std::string> exr_compressions();

// What a write changed: half holds finite values up to 65504 only, so larger finite values are written as
// +-65504 (not as Inf, which is what float-to-half conversion makes of them) and counted here; callers say so.
struct WriteReport {
  int64_t clamped_to_half = 0;
};

// Every check write_exr and write_exr_bands make before writing, for a caller to run before long work: a known
// compression (else Error(Usage), naming the allowed ones), a name ending in .exr (OpenEXR is what is written),
// and prepare_output()'s checks (atomic_file.h: the folder exists and is writable, the file may be replaced).
// Returns the abandoned temporary files of `path` it removed.
std::vector<std::filesystem::path> prepare_exr_output(const std::filesystem::path& path, const ExrWriteOptions& options);

// Writes `image` atomically (atomic_file.h); values are written as they are (NaN and Inf included; float to half
// rounds to nearest; finite values beyond the half range are clamped to it, see WriteReport). Throws residue::Error(Usage) for an unknown compression (naming the allowed ones), a
// channel-name count or data window that does not match the image; residue::Error(Output), with the path and
// OpenImageIO's message, on write failure or an existing file.
WriteReport write_exr(const std::filesystem::path& path, const Image& image, const ExrWriteOptions& options);

// Writes a width x height image that `band(y0, rows)` produces band by band (an Image of width x rows x
// channels, rows = band_rows except maybe the last), so memory stays one band whatever the image size.
// Atomic like write_exr: an exception from `band` (a cancelled denoise, say) leaves no file behind.
using BandSource = std::function<Image(int64_t y0, int64_t rows)>;
WriteReport write_exr_bands(const std::filesystem::path& path, int64_t width, int64_t height, int channels,
                            int64_t band_rows, const ExrWriteOptions& options, const BandSource& band);

}  // namespace residue::io
