#include "core/io/exr_writer.h"

#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <limits>
#include <memory>
#include <string_view>

#include "core/io/atomic_file.h"
#include "core/util/error.h"

namespace residue::io {
namespace fs = std::filesystem;

namespace {

constexpr std::array<std::string_view, 10> kCompressions = {"none",  "rle", "zips", "zip",  "piz",
                                                            "pxr24", "b44", "b44a", "dwaa", "dwab"};

std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

// Accepts one of kCompressions, optionally with a level as OpenEXR takes it: zip and zips 1 to 9, dwaa and
// dwab a positive number (45 by default); the others have none.
void check_compression(const std::string& compression) {
  const auto colon = compression.find(':');
  const std::string base = compression.substr(0, colon);
  if (std::find(kCompressions.begin(), kCompressions.end(), base) == kCompressions.end()) {
    std::string allowed;
    for (auto name : kCompressions) allowed += (allowed.empty() ? "" : ", ") + std::string(name);
    throw Error(ErrorKind::Usage, "unknown EXR compression '" + base + "'; use one of: " + allowed +
                                      " (optionally with a level, e.g. zip:9 or dwaa:45)");
  }
  if (colon == std::string::npos) return;
  const std::string level = compression.substr(colon + 1);
  const bool digits = !level.empty() && level.size() <= 6 &&
                      std::all_of(level.begin(), level.end(), [](unsigned char c) { return std::isdigit(c) != 0; });
  const int value = digits ? std::stoi(level) : -1;
  const std::string where = "EXR compression '" + compression + "': ";
  if (base == "zip" || base == "zips") {
    if (value < 1 || value > 9) throw Error(ErrorKind::Usage, where + "the level of " + base + " is 1 to 9, not '" + level + "'");
  } else if (base == "dwaa" || base == "dwab") {
    if (value < 1) throw Error(ErrorKind::Usage, where + "the level of " + base + " is a positive whole number (45 by default), not '" + level + "'");
  } else {
    throw Error(ErrorKind::Usage, where + base + " takes no level");
  }
}

std::vector<std::string> channel_names(int n, const ExrWriteOptions& options) {
  if (!options.channel_names.empty()) {
    if (static_cast<int>(options.channel_names.size()) != n)
      throw Error(ErrorKind::Usage, std::to_string(options.channel_names.size()) +
                                        " channel names given for an image with " + std::to_string(n) +
                                        " channels");
    return options.channel_names;
  }
  if (n == 1) return {"Y"};
  if (n == 3) return {"R", "G", "B"};
  if (n == 4) return {"R", "G", "B", "A"};
  std::vector<std::string> names;
  for (int c = 0; c < n; ++c) names.push_back("C" + std::to_string(c));
  return names;
}

// Attributes that describe how the source file was laid out or encoded, not what it shows: copying them would
// contradict the file being written (or override its compression). Also the residue:* provenance of an
// earlier run, which the new residue_attributes replace.
bool is_layout_attribute(std::string_view name) {
  // clang-format off
  static constexpr std::array<std::string_view, 22> kNames = {
      "compression", "openexr:compression", "channels", "channellist", "dataWindow", "displayWindow",
      "tiles", "tile_width", "tile_height", "chunkCount", "openexr:chunkCount", "version", "openexr:version",
      "name", "type", "lineOrder", "openexr:lineOrder", "openexr:levelmode", "openexr:roundingmode",
      "openexr:dwaCompressionLevel", "maxSamplesPerPixel", "planarconfig"};
  // clang-format on
  using OIIO::Strutil::iequals, OIIO::Strutil::istarts_with;
  return std::any_of(kNames.begin(), kNames.end(), [&](std::string_view n) { return iequals(name, n); }) ||
         istarts_with(name, "oiio:") || istarts_with(name, "residue:") || istarts_with(name, "openexr:deep");
}

// EXR has string, int, float and double attributes; anything else (int64, unsigned, ...) is written as text.
OIIO::ParamValue as_exr_attribute(const OIIO::ParamValue& p) {
  const OIIO::TypeDesc t = p.type();
  if (p.nvalues() == 1 &&
      (t == OIIO::TypeString || t == OIIO::TypeFloat || t == OIIO::TypeInt || t == OIIO::TypeDesc::DOUBLE))
    return p;
  return OIIO::ParamValue(p.name(), p.get_string());
}

int to_int(int64_t v, const char* what, const fs::path& path) {
  if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max())
    throw Error(ErrorKind::Usage,
                std::string(what) + " " + std::to_string(v) + " is too large for " + quoted(path));
  return static_cast<int>(v);
}

OIIO::ImageSpec make_spec(const fs::path& path, int64_t width, int64_t height, int channels,
                          const ExrWriteOptions& options) {
  if (width <= 0 || height <= 0 || channels < 1)
    throw Error(ErrorKind::Usage, "cannot write an empty image to " + quoted(path));
  const Rect& dw = options.data_window;
  if ((dw.width != 0 || dw.height != 0) && (dw.width != width || dw.height != height))
    throw Error(ErrorKind::Usage, "data window " + dw.to_string() + " does not match the " + std::to_string(width) +
                                      "x" + std::to_string(height) + " image written to " + quoted(path));
  const auto format = options.pixel_type == PixelType::Half ? OIIO::TypeHalf : OIIO::TypeFloat;
  OIIO::ImageSpec spec(to_int(width, "width", path), to_int(height, "height", path), channels, format);
  spec.x = to_int(dw.x, "data window x", path);
  spec.y = to_int(dw.y, "data window y", path);
  spec.full_x = 0;
  spec.full_y = 0;
  spec.full_width =
      to_int(options.display_width > 0 ? options.display_width : width, "display width", path);
  spec.full_height =
      to_int(options.display_height > 0 ? options.display_height : height, "display height", path);
  spec.channelnames = channel_names(channels, options);
  const auto alpha = std::find(spec.channelnames.begin(), spec.channelnames.end(), "A");
  spec.alpha_channel =
      alpha == spec.channelnames.end() ? -1 : static_cast<int>(alpha - spec.channelnames.begin());
  spec.z_channel = -1;

  for (const OIIO::ParamValue& p : options.metadata)
    if (!is_layout_attribute(p.name().string())) spec.extra_attribs.add_or_replace(p);
  for (const OIIO::ParamValue& p : options.residue_attributes)
    spec.extra_attribs.add_or_replace(as_exr_attribute(p));
  // Set last, so that nothing copied above can override the chosen compression.
  spec.attribute("compression", options.compression);
  return spec;
}

}  // namespace

namespace {

// For half output: `image` itself when every finite value fits in half, else a copy with those beyond +-65504
// clamped to it (counted in `report`).
const Image& fit_to_half(const Image& image, const ExrWriteOptions& options, Image& copy, WriteReport& report) {
  constexpr float kHalfMax = 65504.0f;
  if (options.pixel_type != PixelType::Half) return image;
  auto out_of_range = [&](float v) { return std::isfinite(v) && std::abs(v) > kHalfMax; };
  const float* begin = image.data();
  if (std::none_of(begin, begin + image.size(), out_of_range)) return image;
  copy = image;
  for (size_t i = 0; i < copy.size(); ++i) {
    float& v = copy.data()[i];
    if (out_of_range(v)) {
      v = std::copysign(kHalfMax, v);
      ++report.clamped_to_half;
    }
  }
  return copy;
}

}  // namespace

std::vector<fs::path> prepare_exr_output(const fs::path& path, const ExrWriteOptions& options) {
  check_compression(options.compression);
  if (OIIO::Strutil::iequals(path.filename().string(), ".exr"))
    throw Error(ErrorKind::Output, "output " + quoted(path) + " is an extension without a name: give the file a name, e.g. out.exr");
  std::vector<fs::path> removed = prepare_output(path, options.overwrite);
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return std::tolower(c); });
  if (extension != ".exr")
    throw Error(ErrorKind::Output, "output " + quoted(path) + ": the file written is OpenEXR; give it a name ending in .exr");
  return removed;
}

// Written as bands of rows, like a streamed output: OpenImageIO converts to half one band at a time (a whole
// image at once needed a second full-size buffer, and its page faults), and the zip chunks of a band are still
// compressed in parallel.
WriteReport write_exr(const fs::path& path, const Image& image, const ExrWriteOptions& options) {
  constexpr int64_t kBandRows = 256;  // a multiple of every compression's chunk height (at most 32 rows)
  return write_exr_bands(path, image.width(), image.height(), image.channels(), kBandRows, options,
                         [&](int64_t y0, int64_t rows) { return crop(image, {0, y0, image.width(), rows}); });
}

WriteReport write_exr_bands(const fs::path& path, int64_t width, int64_t height, int channels, int64_t band_rows,
                            const ExrWriteOptions& options, const BandSource& band) {
  prepare_exr_output(path, options);
  const OIIO::ImageSpec spec = make_spec(path, width, height, channels, options);
  WriteReport report;
  write_atomically(path, options.overwrite, [&](const fs::path& temp) {
    auto out = OIIO::ImageOutput::create("openexr");
    if (!out) throw Error(ErrorKind::Output, "cannot write " + quoted(path) + ": " + OIIO::geterror());
    if (!out->open(temp.string(), spec))
      throw Error(ErrorKind::Output, "cannot write " + quoted(path) + ": " + out->geterror());
    for (int64_t y0 = 0; y0 < height; y0 += band_rows) {
      const int64_t rows = std::min(band_rows, height - y0);
      const Image rows_image = band(y0, rows);
      if (rows_image.width() != width || rows_image.height() != rows || rows_image.channels() != channels)
        throw Error(ErrorKind::Usage, "band of rows " + std::to_string(y0) + "+" + std::to_string(rows) +
                                          " has the wrong size for " + quoted(path));
      Image copy;
      const Image& pixels = fit_to_half(rows_image, options, copy, report);
      if (!out->write_scanlines(spec.y + static_cast<int>(y0), spec.y + static_cast<int>(y0 + rows), 0,
                                OIIO::TypeFloat, pixels.data()))
        throw Error(ErrorKind::Output, "cannot write " + quoted(path) + ": " + out->geterror());
    }
    if (!out->close()) throw Error(ErrorKind::Output, "cannot write " + quoted(path) + ": " + out->geterror());
  });
  return report;
}

std::vector<std::string> exr_compressions() { return {kCompressions.begin(), kCompressions.end()}; }

}  // namespace residue::io
