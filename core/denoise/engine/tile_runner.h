// Denoises one tile: features of the tile and its halo, the network (under each member of the self-ensemble),
// the output guard, the output transform, the variance blend.
#pragma once

#include <cstdint>

#include "core/aov/aov_stack.h"
#include "core/denoise/engine/network_pass.h"
#include "core/nn/backend.h"
#include "core/util/cancel.h"

namespace residue {

class TileRunner {
 public:
  TileRunner(const NetworkPass& pass, nn::Backend& backend, const NetworkIO& io, const CancelToken* cancel)
      : pass_(pass), backend_(backend), io_(io), cancel_(cancel) {}

  // `src` holds the image's pixels of `src_rect` (image coordinates; it covers the tile `t` and its halo); the
  // result goes to `out` at the tile's position minus (out_x0, out_y0). Returns true when the tile was skipped
  // (all black: written as zeros). Error(Input) when the network gave a non-finite value.
  bool run(const AovStack& src, const Rect& src_rect, const Rect& bounds, const Rect& t, Image& out, int64_t out_x0,
           int64_t out_y0);

  int64_t guarded() const { return guarded_; }  // values the guard clamped so far

 private:
  const NetworkPass& pass_;
  nn::Backend& backend_;
  const NetworkIO& io_;
  const CancelToken* cancel_;
  int64_t guarded_ = 0;
  Image features_, padded_, result_, turned_in_, turned_out_;
};

}  // namespace residue
