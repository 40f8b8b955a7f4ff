#include "core/aov/exr_header_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <vector>

#include "core/util/error.h"
#include "core/util/little_endian.h"

namespace residue {
namespace {

// Headers are a few KB; a mutated one that OpenEXR would misread is caught within the first MiB.
constexpr size_t kHeaderScanBytes = size_t{1} << 20;

std::string too_large(const std::string& what, uint64_t declared, uint64_t file_size) {
  return "its header declares " + what + " of " + std::to_string(declared) + " bytes, but the file holds " +
         std::to_string(file_size) + " (corrupt or truncated)";
}

// OpenEXR reads a fixed-size attribute (box2i, v2f, ...) by its type, whatever size the header declares, so after a
// mutated size its position and a walk of the header part ways; so a type name is looked at wherever it stands.
// Calls visit(value offset, declared size) for each place `type` (and its NUL) stands with its 4-byte size and at
// least `value_bytes` after it; stops at the first problem a visit returns.
template <class Visit>
std::optional<std::string> for_each_typed_value(const uint8_t* bytes, size_t size, const char* type,
                                                size_t value_bytes, Visit&& visit) {
  const size_t len = std::strlen(type) + 1;
  for (size_t p = 0; p + len + 4 + value_bytes <= size; ++p) {
    if (std::memcmp(bytes + p, type, len) != 0) continue;
    if (auto problem = visit(p + len + 4, load_le32(bytes + p + len))) return problem;
  }
  return std::nullopt;
}

// Walks a channel list (the value of a "chlist" attribute at `p`, `n` bytes): per channel a name and its NUL, then
// 16 bytes: pixel type, pLinear and reserved, x and y sampling. Calls visit(name, pixel type, x sampling, y sampling)
// until the list ends or is cut short (OpenEXR reports a truncated list itself), or a visit returns a problem.
template <class Visit>
std::optional<std::string> for_each_channel(const uint8_t* p, size_t n, Visit&& visit) {
  for (size_t pos = 0; pos < n;) {
    const void* nul = std::memchr(p + pos, 0, n - pos);
    if (!nul) return std::nullopt;
    const std::string name(reinterpret_cast<const char*>(p + pos), static_cast<const uint8_t*>(nul) - (p + pos));
    pos += name.size() + 1;
    if (name.empty() || n - pos < 16) return std::nullopt;
    if (auto problem = visit(name, load_le32(p + pos), static_cast<int32_t>(load_le32(p + pos + 8)),
                             static_cast<int32_t>(load_le32(p + pos + 12))))
      return problem;
    pos += 16;
  }
  return std::nullopt;
}

// A channel list: what OpenImageIO cannot take. OpenImageIO 2.4 aborts the process (an assertion) on a pixel type
// other than 0 (uint), 1 (half), 2 (float): found by fuzz_exr_loader.
std::optional<std::string> channel_list_problem(const uint8_t* p, size_t n) {
  return for_each_channel(p, n, [](const std::string& name, uint32_t type, int32_t x_sampling,
                                   int32_t y_sampling) -> std::optional<std::string> {
    if (type > 2)
      return "the channel '" + name + "' has pixel type " + std::to_string(type) +
             "; OpenEXR has 0 (uint), 1 (half) and 2 (float) (corrupt file)";
    if (x_sampling < 1 || y_sampling < 1)
      return "the channel '" + name + "' has sampling " + std::to_string(x_sampling) + "x" +
             std::to_string(y_sampling) + "; expected 1 or more (corrupt file)";
    return std::nullopt;
  });
}

// No OpenEXR codec comes near this ratio of pixel bytes to file bytes (zlib's limit is 1032:1; an all-black DWAB
// image about 10^4:1); below kAlwaysPlausibleBytes a header is never refused for its size.
constexpr double kMaxCompression = 65536;
constexpr double kAlwaysPlausibleBytes = 256.0 * (1 << 20);
// OpenEXR sizes a compressor's buffer for a whole chunk of lines (up to 256, DWAB's) even where the window is lower.
constexpr double kMaxLinesPerChunk = 256;

}  // namespace

ExrDeclaredPixels exr_declared_pixels(const uint8_t* bytes, size_t size) {
  ExrDeclaredPixels out;
  const std::optional<std::string> none;
  for_each_typed_value(bytes, size, "chlist", 0, [&](size_t list, uint32_t declared) {
    double channels = 0, pixel_bytes = 0;
    for_each_channel(bytes + list, std::min<size_t>(declared, size - list), [&](const std::string&, uint32_t type,
                                                                                int32_t, int32_t) {
      channels += 1;
      pixel_bytes += type == 1 ? 2 : 4;  // half, else uint or float
      return none;
    });
    out.channels = std::max(out.channels, channels);
    out.pixel_bytes = std::max(out.pixel_bytes, pixel_bytes);
    return none;
  });
  auto i32 = [&](size_t at) { return static_cast<double>(static_cast<int32_t>(load_le32(bytes + at))); };
  // Display windows apart: nothing is allocated by them (a region render's 64x64 data window may sit in a
  // 16384x8640 display window). The name stands just before the type: "displayWindow\0box2i\0", size, value.
  static constexpr char kDisplayWindow[] = "displayWindow";  // with its NUL: 14 bytes
  constexpr size_t kBeforeValue = sizeof(kDisplayWindow) + sizeof("box2i") + 4;
  for_each_typed_value(bytes, size, "box2i", 16, [&](size_t v, uint32_t) {  // xMin, yMin, xMax, yMax
    const bool display = v >= kBeforeValue && std::memcmp(bytes + v - kBeforeValue, kDisplayWindow, sizeof(kDisplayWindow)) == 0;
    (display ? out.display_windows : out.windows)
        .emplace_back(std::abs(i32(v + 8) - i32(v)) + 1, std::abs(i32(v + 12) - i32(v + 4)) + 1);
    return none;
  });
  for_each_typed_value(bytes, size, "tiledesc", 8, [&](size_t v, uint32_t) {  // tile width, height, level mode
    out.tiles.emplace_back(load_le32(bytes + v), load_le32(bytes + v + 4));
    return none;
  });
  return out;
}

std::optional<std::string> exr_header_problem(const uint8_t* bytes, size_t size, uint64_t file_size) {
  static constexpr uint8_t kMagic[4] = {0x76, 0x2f, 0x31, 0x01};
  if (size < 8 || std::memcmp(bytes, kMagic, 4) != 0) return std::nullopt;

  // Every string's size and every channel list, wherever they stand (for_each_typed_value says why not only the
  // walk's below; both string inputs the fuzzer found are caught this way only; a multipart file has a channel
  // list per part).
  for (const char* type : {"string", "stringvector"})
    if (auto problem = for_each_typed_value(bytes, size, type, 0, [&](size_t, uint32_t n) -> std::optional<std::string> {
          if (n > file_size) return too_large(std::string("a ") + type + " attribute", n, file_size);
          return std::nullopt;
        }))
      return problem;
  if (auto problem = for_each_typed_value(bytes, size, "chlist", 0, [&](size_t value, uint32_t n) {
        return channel_list_problem(bytes + value, std::min<size_t>(n, size - value));
      }))
    return problem;

  // The pixels it declares must fit in the file: opening it, OpenEXR allocates line buffers by the data window, and
  // a reader the whole image (a 3 KB file declaring 33554438 x 6 pixels of 12 float channels cost 8 GB of memory
  // and ended in bad_alloc: found by fuzz_exr_loader).
  const ExrDeclaredPixels declared = exr_declared_pixels(bytes, size);
  const double plausible = std::max(kAlwaysPlausibleBytes, static_cast<double>(file_size) * kMaxCompression);
  for (const auto& [extent, what] : {std::pair{&declared.windows, "a window"}, std::pair{&declared.tiles, "tiles"}})
    for (const auto& [width, height] : *extent) {
      if (width * std::max(height, kMaxLinesPerChunk) * std::max(declared.pixel_bytes, 1.0) <= plausible) continue;
      char text[160];
      std::snprintf(text, sizeof text, "its header declares %s of %.0f x %.0f pixels of %.0f bytes, more than a file of ",
                    what, width, height, declared.pixel_bytes);
      return text + std::to_string(file_size) + " bytes can hold (corrupt or truncated)";
    }

  // The walk: per header (several in a multipart file, an empty one ending the list) name, type, size, value.
  const bool multipart = (bytes[5] & 0x10) != 0;  // version field, bit 12
  size_t pos = 8;
  auto skip_cstring = [&](std::string* out) {
    const void* nul = std::memchr(bytes + pos, 0, size - pos);
    if (!nul) return false;
    const size_t n = static_cast<size_t>(static_cast<const uint8_t*>(nul) - (bytes + pos));
    if (out) out->assign(reinterpret_cast<const char*>(bytes + pos), n);
    pos += n + 1;
    return true;
  };
  while (pos < size) {
    bool empty = true;
    for (;;) {
      std::string name;
      if (pos >= size || !skip_cstring(&name)) return std::nullopt;  // ran past what was read: OpenEXR judges
      if (name.empty()) break;                                          // end of this header
      empty = false;
      if (pos >= size || !skip_cstring(nullptr) || size - pos < 4) return std::nullopt;
      const uint32_t n = load_le32(bytes + pos);
      pos += 4;
      if (n > file_size - std::min<uint64_t>(file_size, pos))
        return too_large("the attribute '" + name + "'", n, file_size);
      if (n > size - pos) return std::nullopt;
      pos += n;
    }
    if (!multipart || empty) break;
  }
  return std::nullopt;
}

void check_exr_header(const std::filesystem::path& path) {
  std::error_code ec;
  const uint64_t file_size = std::filesystem::file_size(path, ec);
  if (ec) return;  // OpenImageIO reports what is wrong with it
  std::ifstream in(path, std::ios::binary);
  if (!in) return;
  std::vector<uint8_t> head(static_cast<size_t>(std::min<uint64_t>(file_size, kHeaderScanBytes)));
  in.read(reinterpret_cast<char*>(head.data()), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(in.gcount()));
  if (auto problem = exr_header_problem(head.data(), head.size(), file_size))
    throw Error(ErrorKind::Input, "cannot read '" + path.string() + "': " + *problem);
}

}  // namespace residue
