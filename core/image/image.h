// Image: a float image with interleaved channels and 64-bit indexing.
//
// Every pixel buffer in Residue is one of these: AOVs, references, metric maps, network outputs.
// Indices are int64_t so that 16K x 16K images with many channels never overflow.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace residue {

// A rectangle of pixels, [x, x+width) x [y, y+height), in the image's own pixel coordinates.
struct Rect {
  int64_t x = 0;
  int64_t y = 0;
  int64_t width = 0;
  int64_t height = 0;

  int64_t area() const { return width * height; }
  bool empty() const { return width <= 0 || height <= 0; }
  bool contains(const Rect& o) const {
    return o.x >= x && o.y >= y && o.x + o.width <= x + width && o.y + o.height <= y + height;
  }
  // The bounding box of both (an empty rectangle adds nothing), and the overlap (empty when there is none).
  Rect united(const Rect& o) const;
  Rect intersected(const Rect& o) const;
  friend bool operator==(const Rect&, const Rect&) = default;
  std::string to_string() const;  // "x,y,w,h"
};

class Image {
 public:
  Image() = default;
  Image(int64_t width, int64_t height, int channels, float fill = 0.0f);

  int64_t width() const { return width_; }
  int64_t height() const { return height_; }
  int channels() const { return channels_; }
  int64_t pixel_count() const { return width_ * height_; }
  bool empty() const { return data_.empty(); }
  Rect bounds() const { return {0, 0, width_, height_}; }

  int64_t offset(int64_t x, int64_t y, int c = 0) const {
    return (y * width_ + x) * channels_ + c;
  }
  float& at(int64_t x, int64_t y, int c = 0) { return data_[static_cast<size_t>(offset(x, y, c))]; }
  float at(int64_t x, int64_t y, int c = 0) const { return data_[static_cast<size_t>(offset(x, y, c))]; }

  // All channels of one row, contiguous.
  std::span<float> row(int64_t y) {
    return {data_.data() + offset(0, y), static_cast<size_t>(width_ * channels_)};
  }
  std::span<const float> row(int64_t y) const {
    return {data_.data() + offset(0, y), static_cast<size_t>(width_ * channels_)};
  }

  float* data() { return data_.data(); }
  const float* data() const { return data_.data(); }
  size_t size() const { return data_.size(); }

 private:
  int64_t width_ = 0;
  int64_t height_ = 0;
  int channels_ = 0;
  std::vector<float> data_;
};

// Counts of pixels values that are not finite numbers, per image or per region.
struct NonFiniteCount {
  int64_t nan = 0;
  int64_t inf = 0;
  int64_t total() const { return nan + inf; }
  NonFiniteCount& operator+=(const NonFiniteCount& o) {
    nan += o.nan;
    inf += o.inf;
    return *this;
  }
};

// Counts NaN and Inf values (not pixels) over all channels; parallel.
NonFiniteCount count_non_finite(const Image& image);

// A copy of `rect` of `image` (rect must lie inside the image).
Image crop(const Image& image, const Rect& rect);

}  // namespace residue
