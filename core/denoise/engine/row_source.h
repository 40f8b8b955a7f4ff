// Where the rows of a denoise come from: a stack in memory (every row at hand, no copy), or the render's files
// read band by band (AovReader), so that a render larger than memory streams through the same tile engine.
#pragma once

#include <cstdint>
#include <vector>

#include "core/aov/aov_loader.h"
#include "core/aov/aov_stack.h"

namespace residue {

// rows() gives a stack and the rectangle of the image it holds; `roles` limits what a source that reads must
// read (empty: every AOV the denoise uses).
class RowSource {
 public:
  virtual ~RowSource() = default;
  virtual const AovStack& layout() const = 0;
  virtual const AovStack* whole() const { return nullptr; }  // in memory: the statistics come from it directly
  struct Rows {
    AovStack owned;  // read from the files (unused in memory)
    const AovStack* stack = nullptr;
    Rect rect;
  };
  virtual Rows rows(int64_t y0, int64_t y1, const std::vector<AovRole>& roles = {}) = 0;
};

class StackRows final : public RowSource {
 public:
  explicit StackRows(const AovStack& stack) : stack_(stack) {}
  const AovStack& layout() const override { return stack_; }
  const AovStack* whole() const override { return &stack_; }
  Rows rows(int64_t, int64_t, const std::vector<AovRole>&) override {
    return {{}, &stack_, {0, 0, stack_.width(), stack_.height()}};
  }

 private:
  const AovStack& stack_;
};

// Reads each row once: consecutive bands overlap by their halos, and the rows a band shares with the one before
// are taken from it instead of the files. The reference is never read (the denoise does not use it).
class ReaderRows final : public RowSource {
 public:
  // `keep`: rows at the bottom of a band that the next one shares (two halos).
  ReaderRows(const AovReader& reader, int64_t keep);
  const AovStack& layout() const override { return reader_.layout(); }
  Rows rows(int64_t y0, int64_t y1, const std::vector<AovRole>& roles) override;

 private:
  const AovReader& reader_;
  int64_t keep_;
  std::vector<AovRole> used_;
  AovStack cached_;  // the bottom rows of the last band
  Rect last_{};
};

}  // namespace residue
