#include "core/io/map_writer.h"

#include <OpenImageIO/imageio.h>

#include "core/io/atomic_file.h"
#include "core/io/exr_writer.h"
#include "core/util/error.h"

namespace residue::io {
namespace fs = std::filesystem;

namespace {

void require_one_channel(const fs::path& path, const Image& map) {
  if (map.channels() != 1 || map.empty())
    throw Error(ErrorKind::Usage, "cannot write '" + path.string() +
                                      "': a map has one channel and pixels, not " +
                                      std::to_string(map.width()) + "x" + std::to_string(map.height()) + "x" +
                                      std::to_string(map.channels()));
}

}  // namespace

void write_map_png(const fs::path& path, const Image& map, const MapPngOptions& options) {
  require_one_channel(path, map);
  const Image rgb = apply_colormap(map, options.colormap, options.scale);
  if (rgb.width() > INT32_MAX || rgb.height() > INT32_MAX)
    throw Error(ErrorKind::Usage, "map too large for PNG: '" + path.string() + "'");
  const OIIO::ImageSpec spec(static_cast<int>(rgb.width()), static_cast<int>(rgb.height()), 3,
                             OIIO::TypeUInt8);
  write_atomically(path, options.overwrite, [&](const fs::path& temp) {
    auto out = OIIO::ImageOutput::create("png");
    if (!out) throw Error(ErrorKind::Output, "cannot write '" + path.string() + "': " + OIIO::geterror());
    // rgb holds exact multiples of 1/255 (apply_colormap), so the conversion to 8 bits is exact.
    if (!out->open(temp.string(), spec) || !out->write_image(OIIO::TypeFloat, rgb.data()) || !out->close())
      throw Error(ErrorKind::Output, "cannot write '" + path.string() + "': " + out->geterror());
  });
}

void write_map_exr(const fs::path& path, const Image& map, bool overwrite) {
  require_one_channel(path, map);
  ExrWriteOptions options;
  options.pixel_type = PixelType::Float;
  options.compression = "zip";
  options.channel_names = {"Y"};
  options.overwrite = overwrite;
  write_exr(path, map, options);
}

}  // namespace residue::io
