#include "core/denoise/engine/row_source.h"

#include <algorithm>
#include <cstring>

namespace residue {

ReaderRows::ReaderRows(const AovReader& reader, int64_t keep) : reader_(reader), keep_(keep) {
  for (AovRole r : {AovRole::Color, AovRole::Albedo, AovRole::Normal, AovRole::Depth, AovRole::Variance})
    if (reader.layout().find(r)) used_.push_back(r);
}

RowSource::Rows ReaderRows::rows(int64_t y0, int64_t y1, const std::vector<AovRole>& roles) {
  const int64_t W = layout().data_window.width;
  Rows r;
  r.rect = {0, y0, W, y1 - y0};
  const bool all = roles.empty();
  const int64_t c0 = last_.y, c1 = last_.y + last_.height;
  if (all && !last_.empty() && c0 <= y0 && y0 < c1 && c1 < y1) {
    // The shared rows from the last band, the rest from the files.
    r.owned = reader_.read({0, c1, W, y1 - c1}, used_);
    for (AovRole role : used_) {
      const Image& prev = cached_.find(role)->image;
      Image& next = r.owned.find(role)->image;
      Image joined(W, y1 - y0, next.channels());
      const size_t row = static_cast<size_t>(W * next.channels());
      std::memcpy(joined.data(), prev.row(y0 - c0).data(), static_cast<size_t>(c1 - y0) * row * sizeof(float));
      std::memcpy(joined.row(c1 - y0).data(), next.data(), next.size() * sizeof(float));
      next = std::move(joined);
    }
  } else {
    r.owned = reader_.read(r.rect, all ? used_ : roles);
  }
  if (all) {  // the bottom rows, for the next band
    const int64_t k = std::min(keep_, y1 - y0);
    last_ = {0, y1 - k, W, k};
    cached_ = AovStack();
    for (AovRole role : used_) cached_.emplace(role).image = crop(r.owned.find(role)->image, {0, y1 - k - y0, W, k});
  }
  r.stack = &r.owned;
  return r;
}

}  // namespace residue
