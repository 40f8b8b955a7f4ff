#include "support/exr_fixture.h"

#include <stdexcept>

#include <OpenImageIO/imageio.h>
#include <Imath/half.h>

namespace residue::testing {

FixtureChannel constant_channel(const std::string& name, float value, bool half) {
  return {name, half, [value](int, int) { return value; }};
}

float as_half(float value) { return static_cast<float>(Imath::half(value)); }

void write_fixture_exr(const std::string& path, const std::vector<FixturePart>& parts) {
  std::vector<OIIO::ImageSpec> specs;
  for (const auto& p : parts) {
    OIIO::ImageSpec spec(p.width, p.height, static_cast<int>(p.channels.size()), OIIO::TypeFloat);
    spec.x = p.x;
    spec.y = p.y;
    spec.full_x = 0;
    spec.full_y = 0;
    spec.full_width = p.full_width ? p.full_width : p.width;
    spec.full_height = p.full_height ? p.full_height : p.height;
    spec.channelnames.clear();
    spec.channelformats.clear();
    for (const auto& c : p.channels) {
      spec.channelnames.push_back(c.name);
      spec.channelformats.push_back(c.half ? OIIO::TypeHalf : OIIO::TypeFloat);
    }
    spec.attribute("compression", "zip");
    if (!p.name.empty()) spec.attribute("name", p.name);
    for (const auto& [k, v] : p.string_attributes) spec.attribute(k, v);
    for (const auto& [k, m] : p.matrix_attributes) spec.attribute(k, OIIO::TypeMatrix44, m.data());
    for (const auto& [k, v] : p.int_attributes) spec.attribute(k, v);
    specs.push_back(spec);
  }
  auto out = OIIO::ImageOutput::create("openexr");
  if (!out) throw std::runtime_error("no EXR writer");
  const bool multi = parts.size() > 1;
  if (multi ? !out->open(path, static_cast<int>(specs.size()), specs.data()) : !out->open(path, specs.front()))
    throw std::runtime_error("cannot open " + path + ": " + out->geterror());
  for (size_t i = 0; i < parts.size(); ++i) {
    const auto& p = parts[i];
    if (i > 0 && !out->open(path, specs[i], OIIO::ImageOutput::AppendSubimage))
      throw std::runtime_error("cannot append part to " + path + ": " + out->geterror());
    const size_t nch = p.channels.size();
    std::vector<float> pixels(static_cast<size_t>(p.width) * static_cast<size_t>(p.height) * nch);
    for (int y = 0; y < p.height; ++y)
      for (int x = 0; x < p.width; ++x)
        for (size_t c = 0; c < nch; ++c)
          pixels[(static_cast<size_t>(y) * static_cast<size_t>(p.width) + static_cast<size_t>(x)) * nch + c] =
              p.channels[c].value(p.x + x, p.y + y);
    if (!out->write_image(OIIO::TypeFloat, pixels.data()))
      throw std::runtime_error("cannot write " + path + ": " + out->geterror());
  }
  out->close();
}

}  // namespace residue::testing
