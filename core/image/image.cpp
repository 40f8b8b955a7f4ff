#include "core/image/image.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

namespace residue {

Rect Rect::united(const Rect& o) const {
  if (o.empty()) return *this;
  if (empty()) return o;
  const int64_t x0 = std::min(x, o.x), y0 = std::min(y, o.y);
  const int64_t x1 = std::max(x + width, o.x + o.width), y1 = std::max(y + height, o.y + o.height);
  return {x0, y0, x1 - x0, y1 - y0};
}

Rect Rect::intersected(const Rect& o) const {
  const int64_t x0 = std::max(x, o.x), y0 = std::max(y, o.y);
  const int64_t x1 = std::min(x + width, o.x + o.width), y1 = std::min(y + height, o.y + o.height);
  return x1 > x0 && y1 > y0 ? Rect{x0, y0, x1 - x0, y1 - y0} : Rect{};
}

std::string Rect::to_string() const {
  return std::to_string(x) + "," + std::to_string(y) + "," + std::to_string(width) + "," +
         std::to_string(height);
}

Image::Image(int64_t width, int64_t height, int channels, float fill)
    : width_(width), height_(height), channels_(channels) {
  if (width < 0 || height < 0 || channels < 0)
    throw std::invalid_argument("Image: negative size " + std::to_string(width) + "x" +
                                std::to_string(height) + "x" + std::to_string(channels));
  data_.assign(static_cast<size_t>(width * height * channels), fill);
}

NonFiniteCount count_non_finite(const Image& image) {
  return tbb::parallel_reduce(
      tbb::blocked_range<int64_t>(0, image.height()), NonFiniteCount{},
      [&](const tbb::blocked_range<int64_t>& rows, NonFiniteCount acc) {
        for (int64_t y = rows.begin(); y != rows.end(); ++y)
          for (float v : image.row(y)) {
            if (std::isnan(v)) ++acc.nan;
            else if (std::isinf(v)) ++acc.inf;
          }
        return acc;
      },
      [](NonFiniteCount a, const NonFiniteCount& b) { return a += b; });
}

Image crop(const Image& image, const Rect& rect) {
  if (!image.bounds().contains(rect))
    throw std::out_of_range("crop: rectangle " + rect.to_string() + " is not inside the " +
                            std::to_string(image.width()) + "x" + std::to_string(image.height()) +
                            " image");
  Image out(rect.width, rect.height, image.channels());
  const size_t row_bytes = static_cast<size_t>(rect.width * image.channels()) * sizeof(float);
  for (int64_t y = 0; y < rect.height; ++y)
    std::memcpy(out.row(y).data(), image.row(rect.y + y).data() + rect.x * image.channels(), row_bytes);
  return out;
}

}  // namespace residue
