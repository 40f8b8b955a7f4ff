#pragma once
// A check of an OpenEXR file's header before OpenImageIO opens it.
//
// OpenEXR 3.1 (Debian 12) allocates and zeroes the size an attribute declares before it reads the value: a 2.6 KB
// file whose header declares a 1.9 GB string attribute costs 1.9 GB of memory before "unexpected end of file"
// (found by fuzz_exr_loader; docs/RELIABILITY.md). No valid file declares an attribute larger than itself, so
// such a header is refused here, naming the attribute, before any allocation. Likewise a channel list with a
// pixel type OpenEXR does not have (OpenImageIO 2.4 aborts the process on it) or a sampling below 1, and a window
// or tile size whose pixels no codec could pack into the file (over 65536:1, and over 256 MiB): OpenEXR sizes its
// buffers by them on opening, 8 GB for a 3 KB file.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace residue {

// What a header declares for its pixels, read from the bytes alone: every window (box2i) and tile size (tiledesc)
// wherever it stands, and the channel list with the most channels / bytes, so that a mutated attribute size, which
// puts a walk of the header out of step with OpenEXR's, cannot hide one. Extents are doubles: two 32-bit extents
// overflow 64 bits.
struct ExrDeclaredPixels {
  std::vector<std::pair<double, double>> windows;          // width, height of each data window
  std::vector<std::pair<double, double>> display_windows;  // ... of each display window (nothing is allocated by it)
  std::vector<std::pair<double, double>> tiles;    // width, height of each tile description
  double channels = 0;                             // of the longest channel list
  double pixel_bytes = 0;                          // of the widest: 2 per half channel, 4 per uint or float
};
ExrDeclaredPixels exr_declared_pixels(const uint8_t* bytes, size_t size);

// What is wrong with the header in `bytes` (the first bytes of a file of `file_size` bytes), or nothing when
// every attribute it declares fits in the file. Bytes that are not OpenEXR pass (OpenImageIO judges them).
std::optional<std::string> exr_header_problem(const uint8_t* bytes, size_t size, uint64_t file_size);

// Reads the start of `path` and throws Error(Input) naming the file when exr_header_problem finds something.
void check_exr_header(const std::filesystem::path& path);

}  // namespace residue
