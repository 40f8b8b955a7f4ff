// The portable fp32 backend: runs a Graph op by op over one arena (arena.h). Each value is NHWC with a zero
// border as wide as the convs that read it need, so a conv reads its neighbours without bounds checks.
// Convs run in parallel on oneTBB, in one of two ways:
//  - on CPUs with AVX-512 (checked at run time): a direct convolution kernel, compiled for AVX-512 through
//    function attributes only, so that the rest of the binary (and Eigen, and the standard library) stays
//    plain x86-64. A tile of 12 pixels x 32 output channels is accumulated in 24 registers over the taps and
//    all input channels, from weights packed per 32-channel block; bias, the activation and the residual add
//    are applied before the store. A concat conv runs one pass per input, accumulating into its output.
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

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define RESIDUE_HAVE_AVX512_KERNEL 1
#endif

#include "core/nn/arena.h"
#include "core/nn/backend.h"
#include "core/util/arena_buffer.h"
#include "core/util/error.h"

namespace residue::nn {
namespace {

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

constexpr int kLanes = 16;       // floats per AVX-512 register
constexpr int kTileBlock = 2;    // output-channel registers per tile (32 channels)
constexpr int kTilePixels = 12;  // pixels per tile: 12 x 2 accumulators, 2 weight registers, 1 broadcast

enum Act { kNone = 0, kRelu = 1, kPrelu = 2 };

int padded_channels(int out) { return (out + kLanes - 1) / kLanes * kLanes; }

// One input of a conv (a concat conv has several): its weights for the AVX-512 kernel, blocked per
// kTileBlock * 16 output channels as [tap][in][channel].
struct ConvPart {
  int value = 0;  // the op whose output this part reads
  int in = 0;     // its channels
  std::vector<float> blocked;
};

// A conv ready to run.
struct PackedConv {
  int out = 0, kernel = 3, dilation = 1;
  Act act = kNone;
  std::vector<ConvPart> parts;
  RowMatrix weights;          // Eigen: (taps * in_total) x out, rows part by part, then tap, then channel
  std::vector<float> bias;    // padded to whole registers with zeros
  std::vector<float> slopes;  // PReLU, padded with ones
};

PackedConv pack(const Graph& g, const GraphOp& op, bool blocked) {
  PackedConv p;
  p.out = op.channels;
  p.kernel = op.kernel;
  p.dilation = op.dilation;
  p.act = op.activation == Activation::ReLU ? kRelu : op.activation == Activation::PReLU ? kPrelu : kNone;
  const int taps = op.kernel * op.kernel;
  const int padded = padded_channels(op.channels);
  p.bias = op.bias;
  p.bias.resize(static_cast<size_t>(padded), 0.0f);
  p.slopes = op.slopes;
  if (!p.slopes.empty()) p.slopes.resize(static_cast<size_t>(padded), 1.0f);
  if (!blocked) p.weights.resize(static_cast<Eigen::Index>(taps) * op.in_channels, op.channels);
  int first = 0;  // the part's first channel in the concatenation
  for (int v : op.inputs) {
    ConvPart part;
    part.value = v;
    part.in = g.op(v).channels;
    if (blocked) {
      part.blocked.assign(static_cast<size_t>(padded) * static_cast<size_t>(taps) * static_cast<size_t>(part.in), 0.0f);
      for (int o0 = 0; o0 < padded; o0 += kTileBlock * kLanes) {
        const int n = std::min(kTileBlock * kLanes, padded - o0);  // channels in this block
        float* block = part.blocked.data() + static_cast<size_t>(o0) * static_cast<size_t>(taps * part.in);
        for (int t = 0; t < taps; ++t)
          for (int i = 0; i < part.in; ++i)
            for (int k = 0; k < n && o0 + k < op.channels; ++k)
              block[(static_cast<size_t>(t) * static_cast<size_t>(part.in) + static_cast<size_t>(i)) * static_cast<size_t>(n) +
                    static_cast<size_t>(k)] = op.w(o0 + k, first + i, t / op.kernel, t % op.kernel);
      }
    } else {
      for (int o = 0; o < op.channels; ++o)
        for (int t = 0; t < taps; ++t)
          for (int i = 0; i < part.in; ++i)
            p.weights(static_cast<Eigen::Index>(taps) * first + t * part.in + i, o) =
                op.w(o, first + i, t / op.kernel, t % op.kernel);
    }
    p.parts.push_back(std::move(part));
    first += g.op(v).channels;
  }
  return p;
}

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

#ifdef RESIDUE_HAVE_AVX512_KERNEL
// What one pass of the kernel does with its sums: + bias, + what dst holds (later parts of a concat conv),
// the activation and + a residual, the last two only on the last pass.
struct Epilogue {
  const float* bias = nullptr;  // null: none
  bool accumulate = false;
  Act act = kNone;
  const float* slopes = nullptr;
  const float* add = nullptr;   // residual at the tile's first pixel; null: none
  int add_c = 0;                // its pixel stride
};

// MR pixels x NR registers of output channels, K x K taps. `src`: the input at pixel (y - d*(K/2), x - ...);
// `w`: the block's weights [tap][in][NR * 16]; `dst` at pixel (y, x), channel o0; `last`: the lanes of the last
// register that are real channels.
template <int MR, int NR, int K>
__attribute__((target("avx512f"))) void tile_avx512(const float* src, int64_t src_row, int cin, int d, const float* w,
                                                    float* dst, int dst_c, const Epilogue& e, __mmask16 last) {
  __m512 acc[MR][NR];
  for (int p = 0; p < MR; ++p)
    for (int j = 0; j < NR; ++j) acc[p][j] = _mm512_setzero_ps();
  for (int ky = 0; ky < K; ++ky)
    for (int kx = 0; kx < K; ++kx) {
      const float* s = src + ky * d * src_row + kx * d * cin;
      const float* wt = w + (ky * K + kx) * cin * NR * kLanes;
      for (int i = 0; i < cin; ++i, wt += NR * kLanes) {
        __m512 wv[NR];
        for (int j = 0; j < NR; ++j) wv[j] = _mm512_loadu_ps(wt + j * kLanes);
        for (int p = 0; p < MR; ++p) {
          const __m512 b = _mm512_set1_ps(s[p * cin + i]);
          for (int j = 0; j < NR; ++j) acc[p][j] = _mm512_fmadd_ps(b, wv[j], acc[p][j]);
        }
      }
    }
  const __m512 zero = _mm512_setzero_ps();
  for (int j = 0; j < NR; ++j) {
    const __mmask16 m = j + 1 == NR ? last : __mmask16(0xFFFF);
    const __m512 bv = e.bias ? _mm512_loadu_ps(e.bias + j * kLanes) : zero;
    const __m512 av = e.act == kPrelu ? _mm512_loadu_ps(e.slopes + j * kLanes) : zero;
    for (int p = 0; p < MR; ++p) {
      __m512 v = _mm512_add_ps(acc[p][j], bv);
      if (e.accumulate) v = _mm512_add_ps(v, _mm512_maskz_loadu_ps(m, dst + p * dst_c + j * kLanes));
      if (e.act == kRelu) v = _mm512_maskz_mov_ps(_mm512_cmp_ps_mask(v, zero, _CMP_GT_OQ), v);  // (max_ps trips -Wmaybe-uninitialized)
      if (e.act == kPrelu) v = _mm512_mask_mul_ps(v, _mm512_cmp_ps_mask(v, zero, _CMP_LT_OQ), v, av);
      if (e.add) v = _mm512_add_ps(v, _mm512_maskz_loadu_ps(m, e.add + p * e.add_c + j * kLanes));
      _mm512_mask_storeu_ps(dst + p * dst_c + j * kLanes, m, v);
    }
  }
}

// The last pixels of a row (fewer than kTilePixels): the tile for exactly `r` of them.
template <int NR, int K, int MR = 1>
__attribute__((target("avx512f"))) void tile_tail_avx512(int r, const float* src, int64_t src_row, int cin, int d,
                                                         const float* w, float* dst, int dst_c, const Epilogue& e,
                                                         __mmask16 last) {
  if constexpr (MR < kTilePixels) {
    if (r == MR) return tile_avx512<MR, NR, K>(src, src_row, cin, d, w, dst, dst_c, e, last);
    tile_tail_avx512<NR, K, MR + 1>(r, src, src_row, cin, d, w, dst, dst_c, e, last);
  }
}

template <int NR, int K>
__attribute__((target("avx512f"))) void block_row_avx512(const float* src, int64_t src_row, int cin, int d,
                                                         int64_t width, const float* w, float* dst, int dst_c,
                                                         Epilogue e, __mmask16 last) {
  int64_t x = 0;
  const float* add = e.add;
  for (; x + kTilePixels <= width; x += kTilePixels) {
    e.add = add ? add + x * e.add_c : nullptr;
    tile_avx512<kTilePixels, NR, K>(src + x * cin, src_row, cin, d, w, dst + x * dst_c, dst_c, e, last);
  }
  if (x < width) {
    e.add = add ? add + x * e.add_c : nullptr;
    tile_tail_avx512<NR, K>(static_cast<int>(width - x), src + x * cin, src_row, cin, d, w, dst + x * dst_c, dst_c, e,
                            last);
  }
}

// One output row of one part, all output channels. `src` at the part's input pixel (y - r, -r) for the conv's
// reach r; `dst` and `add` at pixel (y, 0).
__attribute__((target("avx512f"))) void conv_row_avx512(const PackedConv& c, size_t part, const float* src,
                                                        int64_t src_row, int64_t width, float* dst, int dst_c,
                                                        const float* add, int add_c) {
  const ConvPart& pt = c.parts[part];
  const bool first = part == 0, final = part + 1 == c.parts.size();
  const int padded = padded_channels(c.out);
  const int taps = c.kernel * c.kernel;
  for (int o0 = 0; o0 < padded; o0 += kTileBlock * kLanes) {
    const int regs = std::min(kTileBlock * kLanes, padded - o0) / kLanes;
    const int real = std::min(regs * kLanes, c.out - o0);  // channels of this block that exist
    const int in_last = real - (regs - 1) * kLanes;
    const auto last = static_cast<__mmask16>((1u << in_last) - 1u);
    const float* w = pt.blocked.data() + static_cast<size_t>(o0) * static_cast<size_t>(taps * pt.in);
    Epilogue e;
    e.bias = first ? c.bias.data() + o0 : nullptr;
    e.accumulate = !first;
    e.act = final ? c.act : kNone;
    e.slopes = c.act == kPrelu ? c.slopes.data() + o0 : nullptr;
    e.add = final && add ? add + o0 : nullptr;
    e.add_c = add_c;
    static_assert(kTileBlock == 2, "the instances below assume 2 registers per block");
    if (c.kernel == 3) {
      if (regs == 2) block_row_avx512<2, 3>(src, src_row, pt.in, c.dilation, width, w, dst + o0, dst_c, e, last);
      else block_row_avx512<1, 3>(src, src_row, pt.in, c.dilation, width, w, dst + o0, dst_c, e, last);
    } else {
      if (regs == 2) block_row_avx512<2, 1>(src, src_row, pt.in, c.dilation, width, w, dst + o0, dst_c, e, last);
      else block_row_avx512<1, 1>(src, src_row, pt.in, c.dilation, width, w, dst + o0, dst_c, e, last);
    }
  }
}

bool cpu_has_avx512() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx512f");
}
#else
bool cpu_has_avx512() { return false; }
#endif

constexpr int64_t kStripPixels = 2048;  // im2col rows per GEMM: ~9 MB of patches at W = 128

bool portable_forced() {
  const char* v = std::getenv("RESIDUE_EIGEN_PORTABLE");
  return v != nullptr && *v != '\0' && std::strcmp(v, "0") != 0;
}

class EigenBackend final : public Backend {
 public:
  explicit EigenBackend(const Graph& g)
      : graph_(g), avx512_(cpu_has_avx512() && !portable_forced()) {
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
    if (!avx512_) {
      int widest = 0;
      for (const GraphOp& o : graph_.ops())
        if (o.kind == OpKind::Conv) widest = std::max(widest, o.kernel * o.kernel * o.in_channels + o.channels);
      const auto threads = static_cast<size_t>(tbb::this_task_arena::max_concurrency());
      const auto strip = static_cast<size_t>(std::min(kStripPixels, std::max<int64_t>(width, 1) * height));
      bytes += threads * strip * static_cast<size_t>(widest) * sizeof(float);
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
    const int64_t rows_per_strip = std::max<int64_t>(1, kStripPixels / std::max<int64_t>(w, 1));
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

}  // namespace residue::nn
