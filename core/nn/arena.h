// One memory arena for a graph's values on one tile size. Each value gets an offset; values whose lifetimes
// (from the op that writes them to the last op that reads them) do not overlap share bytes, and a conv whose
// residual is read for the last time writes in place over it (the ResNet's block state). Both backends plan
// with this, each with its own value sizes (padded NHWC for eigen, oneDNN's blocked layouts for onednn).
#pragma once

#include <cstddef>
#include <vector>

#include "core/nn/graph.h"

namespace residue::nn {

struct ArenaPlan {
  std::vector<size_t> offset;  // per op: where its value starts (meaningless where bytes were 0)
  std::vector<int> in_place;   // per op: the value it overwrites in place, or -1
  size_t bytes = 0;            // the arena's size
};

// `bytes[i]`: the size of op i's value in the arena; 0 for values that live elsewhere (the caller's input or
// output). Offsets are multiples of 64.
ArenaPlan plan_arena(const Graph& graph, const std::vector<size_t>& bytes);

}  // namespace residue::nn
