#include "core/denoise/method.h"

#include "core/util/error.h"

namespace residue {

DenoiseStats Method::denoise_to_exr(const AovReader&, const DenoiseOptions&, const std::filesystem::path&,
                                    io::ExrWriteOptions, const TileCallback&, WorkCounter&) const {
  throw Error(ErrorKind::Usage, name() + " needs the whole render in memory; raise --max-memory");
}

DenoiseOptions whole_image_options(const DenoiseOptions& options) {
  DenoiseOptions whole = options;
  whole.roi.reset();
  whole.strength = 1.0f;
  whole.ensemble = 1;
  return whole;
}

TileCallback preliminary(const TileCallback& on_tile) {
  if (!on_tile) return {};
  return [on_tile](const TileEvent& e, const Image& pixels) {
    TileEvent step = e;
    step.result = false;
    return on_tile(step, pixels);
  };
}

int64_t region_pixels(int64_t width, int64_t height, const DenoiseOptions& options) {
  return options.roi ? options.roi->area() : width * height;
}

int ensemble_members(const DenoiseOptions& o, const nn::Model& model) {
  const int n = o.ensemble > 0 ? o.ensemble : model.ensemble;
  if (n != 1 && n != 2 && n != 4 && n != 8)
    throw Error(ErrorKind::Usage, "the self-ensemble has 1, 2, 4 or 8 members (flips and transposes), not " + std::to_string(n));
  return n;
}

}  // namespace residue
