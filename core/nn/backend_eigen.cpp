// The portable fp32 backend: runs a Graph op by op over one arena (arena.h). Each value is NHWC with a zero
// border as wide as the convs that read it need, so a conv reads its neighbours without bounds checks.
// Convs run in parallel on oneTBB, in one of two ways:
//  - on CPUs with AVX-512 (checked at run time): the direct convolution kernel of direct_conv.h, row by row.
//    A concat conv runs one pass per input, accumulating into its output.
//  - otherwise: im2col + Eigen GEMM over strips of rows, the strips in parallel, bias, the activation and
//    the residual add applied while the strip is still in cache.
// Pool, upsample and add are plain loops over rows in parallel.
// RESIDUE_EIGEN_PORTABLE=1 in the environment forces the second way (for tests and comparisons).
#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <map>

#include <Eigen/Core>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "core/nn/arena.h"
#include "core/nn/backend.h"
#include "core/nn/direct_conv.h"
#include "core/util/arena_buffer.h"
#include "core/util/error.h"

namespace residue::nn {
namespace {

using direct_conv::PackedConv;
using direct_conv::pack;
using direct_conv::cpu_has_avx512;
using direct_conv::RowMatrix;
using direct_conv::kRelu;
using direct_conv::kPrelu;
#ifdef RESIDUE_HAVE_AVX512_KERNEL
using direct_conv::conv_row_avx512;
#endif

// A value in the arena: h x w pixels of c channels with a zero border of b pixels around them.
struct Value {
  float* base = nullptr;
  int64_t h = 0, w = 0, b = 0;
  int c = 0;
  int64_t row() const { return (w + 2 * b) * c; }
  float* at(int64_t y, int64_t x) const { return base + (y + b) * row() + (x + b) * c; }
  size_t floats() const { return static_cast<size_t>((h + 2 * b) * (w + 2 * b) * c); }
  void zero_border() const {
    if (b == 0) return;
    const size_t full = static_cast<size_t>(row());
    for (int64_t y = -b; y < h + b; ++y) {
      if (y < 0 || y >= h) {
        std::memset(at(y, -b), 0, full * sizeof(float));
      } else {
        std::memset(at(y, -b), 0, static_cast<size_t>(b * c) * sizeof(float));
        std::memset(at(y, w), 0, static_cast<size_t>(b * c) * sizeof(float));
      }
    }
  }
};

// The rows of one im2col GEMM: a strip of about kStripBytes of patches and results per thread, at least one
// row. Small, so that a band's tight --max-memory holds it; from 128 to 2048 pixels a strip the speed is the same
// within 5 % (docs/PERFORMANCE.md, "The portable path").
constexpr int64_t kStripBytes = int64_t{64} << 10;

int64_t strip_rows(int64_t width, int64_t floats_per_pixel) {
  return std::max<int64_t>(1, kStripBytes / (std::max<int64_t>(width, 1) * floats_per_pixel * int64_t{sizeof(float)}));
}

bool portable_forced() {
  const char* v = std::getenv("RESIDUE_EIGEN_PORTABLE");
  return v != nullptr && *v != '\0' && std::strcmp(v, "0") != 0;
}

class EigenBackend final : public Backend {
 public:
  explicit EigenBackend(const Graph& g)
      : graph_(g), avx512_(eigen_runs_direct_kernel()) {
    convs_.resize(static_cast<size_t>(g.size()));
    for (int i = 0; i < g.size(); ++i)
      if (g.op(i).kind == OpKind::Conv) convs_[static_cast<size_t>(i)] = pack(g, g.op(i), avx512_);
    // One border for every value (the widest any conv reads), so that a value written in place over its
    // residual has the same layout; the output has none (nothing reads it).
    const std::vector<int> b = g.borders();
    border_ = std::max(1, *std::max_element(b.begin(), b.end()));
  }

  std::string description() const override { return avx512_ ? "eigen fp32 (avx512 direct)" : "eigen fp32"; }

  size_t scratch_bytes(int64_t width, int64_t height) const override {
    size_t bytes = plan_for(height, width).arena.bytes;
    if (!avx512_) {  // each thread's strip, as conv_eigen sizes it for the conv that needs the most
      int64_t strip = 0;
      for (const GraphOp& o : graph_.ops())
        if (o.kind == OpKind::Conv) {
          const int64_t w = width >> o.level, h = height >> o.level;
          const int64_t floats = int64_t{o.kernel} * o.kernel * o.in_channels + o.channels;
          strip = std::max(strip, std::min(h, strip_rows(w, floats)) * w * floats * int64_t{sizeof(float)});
        }
      bytes += static_cast<size_t>(tbb::this_task_arena::max_concurrency()) * static_cast<size_t>(strip);
    }
    return bytes;
  }

  void execute(const Image& input, Image& output, const CancelToken* cancel, const std::optional<Rect>& needed) override {
    graph_.check_tile(input);
    const int64_t h = input.height(), w = input.width();
    output = Image(w, h, graph_.output_channels());
    if (h == 0 || w == 0) return;
    const Plan& plan = plan_for(h, w);
    arena_.grow(plan.arena.bytes);
    auto* base = static_cast<float*>(arena_.data());
    std::vector<Value> values(static_cast<size_t>(graph_.size()));
    for (int i = 0; i < graph_.size(); ++i) {
      Value& v = values[static_cast<size_t>(i)];
      v = plan.values[static_cast<size_t>(i)];
      v.base = base + plan.arena.offset[static_cast<size_t>(i)] / sizeof(float);
    }
    Value& out = values[static_cast<size_t>(graph_.output())];
    out.base = output.data();  // the output value is the caller's image (no border: nothing reads it)
    // Each op computes only the pixels that what is needed of the output depends on (all of them by default).
    const std::vector<Rect> regions = graph_.needed_regions(h, w, needed.value_or(Rect{0, 0, w, h}));

    for (int i = 0; i < graph_.size(); ++i) {
      throw_if_cancelled(cancel);
      const GraphOp& op = graph_.op(i);
      const Value& dst = values[static_cast<size_t>(i)];
      const Rect& region = regions[static_cast<size_t>(i)];
      if (region.empty() && op.kind != OpKind::Input) continue;  // nothing needed reads it
      if (plan.arena.in_place[static_cast<size_t>(i)] < 0) dst.zero_border();
      switch (op.kind) {
        case OpKind::Input:
          for (int64_t y = 0; y < h; ++y)
            std::memcpy(dst.at(y, 0), input.row(y).data(), static_cast<size_t>(w * input.channels()) * sizeof(float));
          break;
        case OpKind::Conv: {
          const Value* add = op.residual >= 0 ? &values[static_cast<size_t>(op.residual)] : nullptr;
          std::vector<const Value*> srcs;
          for (int x : op.inputs) srcs.push_back(&values[static_cast<size_t>(x)]);
          conv(convs_[static_cast<size_t>(i)], srcs, dst, add, region, cancel);
          break;
        }
        case OpKind::Pool: pool(values[static_cast<size_t>(op.inputs[0])], dst, region); break;
        case OpKind::Upsample: upsample(values[static_cast<size_t>(op.inputs[0])], dst, region); break;
        case OpKind::Add:
          add(values[static_cast<size_t>(op.inputs[0])], values[static_cast<size_t>(op.inputs[1])], dst, region);
          break;
      }
    }
    throw_if_cancelled(cancel);  // a conv stopped part-way leaves rows unwritten
  }

 private:
  struct Plan {
    std::vector<Value> values;  // shapes (base pointers unset)
    ArenaPlan arena;
  };

  const Plan& plan_for(int64_t h, int64_t w) const {
    const auto key = std::make_pair(h, w);
    if (auto it = plans_.find(key); it != plans_.end()) return it->second;
    if (plans_.size() >= 16) plans_.clear();  // tile sizes are few; this only bounds a pathological caller
    Plan p;
    std::vector<size_t> bytes(static_cast<size_t>(graph_.size()), 0);
    for (int i = 0; i < graph_.size(); ++i) {
      const GraphOp& op = graph_.op(i);
      Value v;
      v.h = h >> op.level;
      v.w = w >> op.level;
      v.c = op.channels;
      v.b = i == graph_.output() ? 0 : border_;
      p.values.push_back(v);
      if (i != graph_.output()) bytes[static_cast<size_t>(i)] = v.floats() * sizeof(float);
    }
    p.arena = plan_arena(graph_, bytes);
    return plans_.emplace(key, std::move(p)).first->second;
  }

  // dst = act(conv(cat(srcs)) + bias) (+ add) over `region` of dst. `dst` may alias `add` (the residual), never a
  // source. Once `cancel` is raised the remaining rows are left undone (the caller throws).
  void conv(const PackedConv& c, const std::vector<const Value*>& srcs, const Value& dst, const Value* add,
            const Rect& region, const CancelToken* cancel) {
#ifdef RESIDUE_HAVE_AVX512_KERNEL
    if (avx512_) {
      const int r = c.dilation * (c.kernel / 2);
      const int64_t x0 = region.x;
      tbb::parallel_for(tbb::blocked_range<int64_t>(region.y, region.y + region.height),
                        [&](const tbb::blocked_range<int64_t>& rows) {
        for (int64_t y = rows.begin(); y < rows.end(); ++y) {
          if (cancel != nullptr && cancel->requested()) return;
          for (size_t p = 0; p < srcs.size(); ++p)
            conv_row_avx512(c, p, srcs[p]->at(y - r, x0 - r), srcs[p]->row(), region.width, dst.at(y, x0), dst.c,
                            add ? add->at(y, x0) : nullptr, add ? add->c : 0);
        }
      });
      return;
    }
#endif
    conv_eigen(c, srcs, dst, add, region, cancel);
  }

  void conv_eigen(const PackedConv& c, const std::vector<const Value*>& srcs, const Value& dst, const Value* add,
                  const Rect& region, const CancelToken* cancel) {
    const int64_t w = region.width, x0 = region.x;
    const int k = c.kernel, r = c.dilation * (k / 2);
    const auto cols = static_cast<int64_t>(c.weights.rows());
    const int64_t rows_per_strip = strip_rows(w, cols + c.out);
    const int64_t strips = (region.height + rows_per_strip - 1) / rows_per_strip;
    tbb::parallel_for(int64_t{0}, strips, [&](int64_t s) {
      if (cancel != nullptr && cancel->requested()) return;
      const int64_t y0 = region.y + s * rows_per_strip, y1 = std::min(region.y + region.height, y0 + rows_per_strip);
      const int64_t pixels = (y1 - y0) * w;
      Scratch& scratch = scratch_.local();
      scratch.cols.resize(static_cast<size_t>(pixels * cols));
      scratch.result.resize(static_cast<size_t>(pixels * c.out));
      // Patches: for each pixel, each input's KxK neighbourhood (the borders supply the zeros).
      for (int64_t y = y0; y < y1; ++y)
        for (int64_t x = 0; x < w; ++x) {
          float* to = scratch.cols.data() + ((y - y0) * w + x) * cols;
          for (const Value* v : srcs)
            for (int ky = 0; ky < k; ++ky)
              for (int kx = 0; kx < k; ++kx, to += v->c)
                std::memcpy(to, v->at(y - r + ky * c.dilation, x0 + x - r + kx * c.dilation),
                            static_cast<size_t>(v->c) * sizeof(float));
        }
      Eigen::Map<const RowMatrix> patches(scratch.cols.data(), pixels, cols);
      Eigen::Map<RowMatrix> result(scratch.result.data(), pixels, c.out);
      result.noalias() = patches * c.weights;
      for (int64_t p = 0; p < pixels; ++p) {
        const int64_t y = y0 + p / w, x = x0 + p % w;
        const float* res = scratch.result.data() + p * c.out;
        const float* a = add ? add->at(y, x) : nullptr;
        float* v = dst.at(y, x);
        for (int o = 0; o < c.out; ++o) {
          float value = res[o] + c.bias[static_cast<size_t>(o)];
          if (c.act == kRelu) value = std::max(value, 0.0f);
          if (c.act == kPrelu && value < 0) value *= c.slopes[static_cast<size_t>(o)];
          if (a) value += a[o];
          v[o] = value;
        }
      }
    });
  }

  static void pool(const Value& src, const Value& dst, const Rect& region) {
    tbb::parallel_for(region.y, region.y + region.height, [&](int64_t y) {
      for (int64_t x = region.x; x < region.x + region.width; ++x) {
        const float *a = src.at(2 * y, 2 * x), *b = src.at(2 * y, 2 * x + 1);
        const float *c = src.at(2 * y + 1, 2 * x), *d = src.at(2 * y + 1, 2 * x + 1);
        float* o = dst.at(y, x);
        for (int k = 0; k < dst.c; ++k) o[k] = std::max(std::max(a[k], b[k]), std::max(c[k], d[k]));
      }
    });
  }

  static void upsample(const Value& src, const Value& dst, const Rect& region) {
    const size_t bytes = static_cast<size_t>(dst.c) * sizeof(float);
    tbb::parallel_for(region.y, region.y + region.height, [&](int64_t y) {
      for (int64_t x = region.x; x < region.x + region.width; ++x) std::memcpy(dst.at(y, x), src.at(y / 2, x / 2), bytes);
    });
  }

  static void add(const Value& a, const Value& b, const Value& dst, const Rect& region) {
    tbb::parallel_for(region.y, region.y + region.height, [&](int64_t y) {
      for (int64_t x = region.x; x < region.x + region.width; ++x) {
        const float *p = a.at(y, x), *q = b.at(y, x);
        float* o = dst.at(y, x);
        for (int k = 0; k < dst.c; ++k) o[k] = p[k] + q[k];
      }
    });
  }

  struct Scratch {
    std::vector<float> cols, result;
  };

  Graph graph_;
  bool avx512_ = false;
  int64_t border_ = 1;
  std::vector<PackedConv> convs_;
  mutable std::map<std::pair<int64_t, int64_t>, Plan> plans_;
  ArenaBuffer arena_;
  tbb::enumerable_thread_specific<Scratch> scratch_;
};

}  // namespace

std::unique_ptr<Backend> make_eigen_backend(const Graph& graph) { return std::make_unique<EigenBackend>(graph); }

bool eigen_runs_direct_kernel() { return cpu_has_avx512() && !portable_forced(); }

}  // namespace residue::nn
