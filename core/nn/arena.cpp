#include "core/nn/arena.h"

#include <algorithm>
#include <numeric>

namespace residue::nn {
namespace {

size_t aligned(size_t b) { return (b + 63) / 64 * 64; }

}  // namespace

ArenaPlan plan_arena(const Graph& graph, const std::vector<size_t>& bytes) {
  const int n = graph.size();
  const std::vector<int> last = graph.last_uses();
  ArenaPlan plan;
  plan.offset.assign(static_cast<size_t>(n), 0);
  plan.in_place.assign(static_cast<size_t>(n), -1);

  // Buffers: a value and the values written in place over it. owner[i] = the buffer value i lives in.
  std::vector<int> owner(static_cast<size_t>(n));
  std::iota(owner.begin(), owner.end(), 0);
  std::vector<int> begin(static_cast<size_t>(n)), end(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const auto u = static_cast<size_t>(i);
    begin[u] = i;
    end[u] = last[u] < 0 ? n : last[u];  // the output (and unused values) live to the end
    const GraphOp& o = graph.op(i);
    const int r = o.residual;
    // In place only over a residual that no one reads afterwards and that the conv does not also read as an input
    // (it would overwrite rows that neighbouring output rows still read).
    const bool also_input = std::find(o.inputs.begin(), o.inputs.end(), r) != o.inputs.end();
    if (o.kind == OpKind::Conv && r >= 0 && !also_input && last[static_cast<size_t>(r)] == i && bytes[static_cast<size_t>(r)] > 0 &&
        bytes[static_cast<size_t>(r)] == bytes[u] && graph.output() != i) {
      plan.in_place[u] = r;
      owner[u] = owner[static_cast<size_t>(r)];
    }
  }
  std::vector<int> lo(static_cast<size_t>(n), n + 1), hi(static_cast<size_t>(n), -1);
  std::vector<size_t> size(static_cast<size_t>(n), 0);
  for (int i = 0; i < n; ++i) {
    const auto b = static_cast<size_t>(owner[static_cast<size_t>(i)]);
    if (bytes[static_cast<size_t>(i)] == 0) continue;
    lo[b] = std::min(lo[b], begin[static_cast<size_t>(i)]);
    hi[b] = std::max(hi[b], end[static_cast<size_t>(i)]);
    size[b] = std::max(size[b], aligned(bytes[static_cast<size_t>(i)]));
  }

  // Greedy placement, largest first: the lowest offset that overlaps no placed buffer alive at the same time.
  std::vector<int> order;
  for (int b = 0; b < n; ++b)
    if (size[static_cast<size_t>(b)] > 0) order.push_back(b);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return size[static_cast<size_t>(a)] > size[static_cast<size_t>(b)]; });
  std::vector<int> placed;
  std::vector<size_t> at(static_cast<size_t>(n), 0);
  for (int b : order) {
    const auto ub = static_cast<size_t>(b);
    std::vector<std::pair<size_t, size_t>> busy;  // address ranges of placed buffers alive with b
    for (int p : placed) {
      const auto up = static_cast<size_t>(p);
      if (lo[up] <= hi[ub] && lo[ub] <= hi[up]) busy.emplace_back(at[up], at[up] + size[up]);
    }
    std::sort(busy.begin(), busy.end());
    size_t offset = 0;
    for (const auto& [s, e] : busy) {
      if (offset + size[ub] <= s) break;
      offset = std::max(offset, e);
    }
    at[ub] = offset;
    plan.bytes = std::max(plan.bytes, offset + size[ub]);
    placed.push_back(b);
  }
  for (int i = 0; i < n; ++i) plan.offset[static_cast<size_t>(i)] = at[static_cast<size_t>(owner[static_cast<size_t>(i)])];
  return plan;
}

}  // namespace residue::nn
