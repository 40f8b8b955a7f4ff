#include "core/denoise/converged_regions.h"

#include <algorithm>
#include <cmath>

#include "core/denoise/variance_blend.h"
#include "core/util/error.h"

namespace residue {
namespace {

// Summed-area table of a w x h grid (row-major), one wider and taller, so that any box sums in four reads.
template <class T>
std::vector<T> summed(const std::vector<T>& v, int64_t w, int64_t h) {
  std::vector<T> s(static_cast<size_t>((w + 1) * (h + 1)), T{});
  for (int64_t y = 0; y < h; ++y) {
    T row{};
    for (int64_t x = 0; x < w; ++x) {
      row += v[static_cast<size_t>(y * w + x)];
      s[static_cast<size_t>((y + 1) * (w + 1) + x + 1)] = s[static_cast<size_t>(y * (w + 1) + x + 1)] + row;
    }
  }
  return s;
}

template <class T>
T box_sum(const std::vector<T>& s, int64_t w, int64_t x0, int64_t y0, int64_t x1, int64_t y1) {  // [x0, x1) x [y0, y1)
  const auto at = [&](int64_t x, int64_t y) { return s[static_cast<size_t>(y * (w + 1) + x)]; };
  return at(x1, y1) - at(x0, y1) - at(x1, y0) + at(x0, y0);
}

// Blocks (of the region's block grid) that need the network: any pixel whose relative variance exceeds the
// threshold, or that is not finite.
std::vector<uint8_t> blocks_needing_network(const AovStack& stack, const Rect& region, float threshold, int64_t bw,
                                            int64_t bh) {
  const Image& colour = stack.color.image;
  const Image& var = stack.variance->image;
  const int vc = var.channels();
  const int64_t w = region.width, h = region.height, r = VarianceBlend::kRadius;
  std::vector<double> lum(static_cast<size_t>(w * h)), v(static_cast<size_t>(w * h)), ok(static_cast<size_t>(w * h));
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x) {
      double l = 0, s = 0;
      for (int c = 0; c < 3; ++c) l += colour.at(region.x + x, region.y + y, c) / 3.0;
      for (int c = 0; c < vc; ++c) s += var.at(region.x + x, region.y + y, c) / static_cast<double>(vc);
      const size_t i = static_cast<size_t>(y * w + x);
      const bool finite = std::isfinite(l) && std::isfinite(s);
      lum[i] = finite ? l : 0.0;
      v[i] = finite ? std::max(s, 0.0) : 0.0;
      ok[i] = finite ? 1.0 : 0.0;
    }
  const std::vector<double> sl = summed(lum, w, h), sv = summed(v, w, h), sn = summed(ok, w, h);
  std::vector<uint8_t> need(static_cast<size_t>(bw * bh), 0);
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x) {
      uint8_t& b = need[static_cast<size_t>((y / ConvergedPlan::kBlock) * bw + x / ConvergedPlan::kBlock)];
      if (b) continue;
      const int64_t x0 = std::max<int64_t>(0, x - r), x1 = std::min(w, x + r + 1);
      const int64_t y0 = std::max<int64_t>(0, y - r), y1 = std::min(h, y + r + 1);
      const double n = box_sum(sn, w, x0, y0, x1, y1);
      if (ok[static_cast<size_t>(y * w + x)] == 0.0 || n == 0.0) {
        b = 1;
        continue;
      }
      const double mean_lum = box_sum(sl, w, x0, y0, x1, y1) / n;
      const double rv = (box_sum(sv, w, x0, y0, x1, y1) / n) / (mean_lum * mean_lum + VarianceBlend::kEps);
      if (!(rv <= threshold)) b = 1;
    }
  return need;
}

// Rectangles (in blocks of the region's grid) covering every marked block, for the least the network computes.
class CoverSearch {
 public:
  CoverSearch(const std::vector<uint8_t>& covered, int64_t bw, int64_t bh, const Rect& region, int64_t halo, const Rect& bounds)
      : bw_(bw), bh_(bh), region_(region), halo_(halo), bounds_(bounds) {
    std::vector<int64_t> ones(covered.begin(), covered.end());
    sum_ = summed(ones, bw, bh);
  }

  void cut(Rect blocks, std::vector<Rect>& out) const {
    blocks = bbox(blocks);
    if (blocks.empty()) return;
    const int64_t whole = cost(blocks);
    int64_t best = whole;
    Rect best_a, best_b;
    for (int64_t c = 1; c < blocks.width; ++c) {
      const Rect a = bbox({blocks.x, blocks.y, c, blocks.height}), b = bbox({blocks.x + c, blocks.y, blocks.width - c, blocks.height});
      if (const int64_t k = cost(a) + cost(b); k < best) best = k, best_a = a, best_b = b;
    }
    for (int64_t c = 1; c < blocks.height; ++c) {
      const Rect a = bbox({blocks.x, blocks.y, blocks.width, c}), b = bbox({blocks.x, blocks.y + c, blocks.width, blocks.height - c});
      if (const int64_t k = cost(a) + cost(b); k < best) best = k, best_a = a, best_b = b;
    }
    if (best >= whole) {
      out.push_back(blocks);
      return;
    }
    cut(best_a, out);
    cut(best_b, out);
  }

  Rect pixels(const Rect& b) const {
    const int64_t x0 = region_.x + b.x * ConvergedPlan::kBlock, y0 = region_.y + b.y * ConvergedPlan::kBlock;
    const int64_t x1 = std::min(region_.x + region_.width, region_.x + (b.x + b.width) * ConvergedPlan::kBlock);
    const int64_t y1 = std::min(region_.y + region_.height, region_.y + (b.y + b.height) * ConvergedPlan::kBlock);
    return {x0, y0, x1 - x0, y1 - y0};
  }

  int64_t cost(const std::vector<Rect>& blocks) const {
    int64_t n = 0;
    for (const Rect& b : blocks) n += cost(b);
    return n;
  }

  // Bottom-up: the runs of covered blocks along each row (of cells of f x f blocks, f doubled until there are at
  // most kMaxRuns), stacked where a run continues unchanged on the next row, then merged two at a time into their
  // bounding box while a merge lowers the cost, the best merge first. This finds what no single cut of the
  // top-down search opens, such as a ring of noise round a converged hole (its four sides). Rectangles may
  // overlap; each is its covered blocks' bounding box in the end.
  std::vector<Rect> merged() const {
    constexpr size_t kMaxRuns = 256;
    std::vector<Rect> r;
    for (int64_t f = 1;; f *= 2) {
      r = runs(f);
      if (r.size() <= kMaxRuns || f >= std::max(bw_, bh_)) break;
    }
    if (r.size() > kMaxRuns) return {};
    std::vector<int64_t> c(r.size());
    for (size_t i = 0; i < r.size(); ++i) c[i] = cost(r[i]);
    for (;;) {
      int64_t best = 0;
      size_t bi = 0, bj = 0;
      for (size_t i = 0; i < r.size(); ++i)
        for (size_t j = i + 1; j < r.size(); ++j)
          if (const int64_t saving = c[i] + c[j] - cost(r[i].united(r[j])); saving > best) best = saving, bi = i, bj = j;
      if (best == 0) break;
      const Rect m = r[bi].united(r[bj]);
      std::vector<Rect> next{m};
      for (size_t k = 0; k < r.size(); ++k)
        if (k != bi && k != bj && !m.contains(r[k])) next.push_back(r[k]);
      r = std::move(next);
      c.resize(r.size());
      for (size_t i = 0; i < r.size(); ++i) c[i] = cost(r[i]);
    }
    std::vector<Rect> out;
    for (const Rect& b : r)
      if (const Rect t = bbox(b); !t.empty()) out.push_back(t);
    return out;
  }

 private:
  int64_t count(const Rect& b) const { return box_sum(sum_, bw_, b.x, b.y, b.x + b.width, b.y + b.height); }

  // The smallest rectangle holding the covered blocks of `b` (empty when there are none).
  Rect bbox(Rect b) const {
    if (b.empty() || count(b) == 0) return {};
    while (count({b.x, b.y, b.width, 1}) == 0) ++b.y, --b.height;
    while (count({b.x, b.y + b.height - 1, b.width, 1}) == 0) --b.height;
    while (count({b.x, b.y, 1, b.height}) == 0) ++b.x, --b.width;
    while (count({b.x + b.width - 1, b.y, 1, b.height}) == 0) --b.width;
    return b;
  }

  int64_t cost(const Rect& b) const { return b.empty() ? 0 : network_pixels({pixels(b)}, halo_, bounds_); }

  // The row runs of covered cells of f x f blocks, in blocks, stacked down while unchanged.
  std::vector<Rect> runs(int64_t f) const {
    std::vector<Rect> done, open;  // open: the runs that reach the previous cell row
    for (int64_t y = 0; y < bh_; y += f) {
      const int64_t h = std::min(f, bh_ - y);
      std::vector<Rect> row;
      for (int64_t x = 0; x < bw_;) {
        const auto covered = [&](int64_t cx) { return count({cx, y, std::min(f, bw_ - cx), h}) > 0; };
        if (!covered(x)) {
          x += f;
          continue;
        }
        int64_t end = x;
        while (end < bw_ && covered(end)) end += f;
        end = std::min(end, bw_);
        row.push_back({x, y, end - x, h});
        x = end;
      }
      std::vector<Rect> still;
      for (Rect& o : open) {
        bool continued = false;
        for (Rect& n : row)
          if (n.width > 0 && n.x == o.x && n.width == o.width) {
            o.height += n.height;
            n.width = 0;
            continued = true;
          }
        (continued ? still : done).push_back(o);
      }
      for (const Rect& n : row)
        if (n.width > 0) still.push_back(n);
      open = std::move(still);
    }
    done.insert(done.end(), open.begin(), open.end());
    return done;
  }

  int64_t bw_, bh_;
  Rect region_;
  int64_t halo_;
  Rect bounds_;
  std::vector<int64_t> sum_;
};

}  // namespace

int64_t network_pixels(const std::vector<Rect>& regions, int64_t halo, const Rect& bounds) {
  int64_t n = 0;
  for (const Rect& r : regions) n += Rect{r.x - halo, r.y - halo, r.width + 2 * halo, r.height + 2 * halo}.intersected(bounds).area();
  return n;
}

ConvergedPlan plan_converged(const AovStack& stack, const Rect& region, float threshold, int64_t halo) {
  if (!stack.variance) throw Error(ErrorKind::Input, "plan_converged: the stack has no variance AOV");
  constexpr int64_t B = ConvergedPlan::kBlock, F = ConvergedPlan::kFeather;
  const int64_t bw = (region.width + B - 1) / B, bh = (region.height + B - 1) / B;
  const std::vector<uint8_t> need = blocks_needing_network(stack, region, threshold, bw, bh);

  // The weight: 1 on the blocks that need the network, falling to 0 over F px away from them (the chessboard
  // distance, by a two-pass chamfer transform with unit steps, exact for it).
  ConvergedPlan plan;
  const int64_t w = region.width, h = region.height;
  const int64_t far = w + h + F;
  std::vector<int64_t> d(static_cast<size_t>(w * h));
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x) d[static_cast<size_t>(y * w + x)] = need[static_cast<size_t>((y / B) * bw + x / B)] ? 0 : far;
  const auto at = [&](int64_t x, int64_t y) -> int64_t& { return d[static_cast<size_t>(y * w + x)]; };
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x) {
      int64_t& v = at(x, y);
      if (x > 0) v = std::min(v, at(x - 1, y) + 1);
      if (y > 0) {
        v = std::min(v, at(x, y - 1) + 1);
        if (x > 0) v = std::min(v, at(x - 1, y - 1) + 1);
        if (x + 1 < w) v = std::min(v, at(x + 1, y - 1) + 1);
      }
    }
  for (int64_t y = h - 1; y >= 0; --y)
    for (int64_t x = w - 1; x >= 0; --x) {
      int64_t& v = at(x, y);
      if (x + 1 < w) v = std::min(v, at(x + 1, y) + 1);
      if (y + 1 < h) {
        v = std::min(v, at(x, y + 1) + 1);
        if (x + 1 < w) v = std::min(v, at(x + 1, y + 1) + 1);
        if (x > 0) v = std::min(v, at(x - 1, y + 1) + 1);
      }
    }
  plan.weight = Image(w, h, 1);
  std::vector<uint8_t> covered(static_cast<size_t>(bw * bh), 0);
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x) {
      const int64_t dist = at(x, y);
      const float weight = dist >= F ? 0.0f : 1.0f - static_cast<float>(dist) / static_cast<float>(F);
      plan.weight.at(x, y, 0) = weight;
      if (weight > 0.0f) covered[static_cast<size_t>((y / B) * bw + x / B)] = 1;
      else ++plan.kept_pixels;
    }
  const Rect bounds{0, 0, stack.width(), stack.height()};
  // Two searches, the cheaper plan kept: cutting the bounding box down, and merging the rows' runs up.
  const CoverSearch search(covered, bw, bh, region, halo, bounds);
  std::vector<Rect> cut, merged = search.merged();
  search.cut({0, 0, bw, bh}, cut);
  const std::vector<Rect>& best = !merged.empty() && search.cost(merged) < search.cost(cut) ? merged : cut;
  for (const Rect& b : best) plan.regions.push_back(search.pixels(b));
  plan.network_pixels = network_pixels(plan.regions, halo, bounds);
  return plan;
}

}  // namespace residue
