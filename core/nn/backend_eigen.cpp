// The portable fp32 backend. Activations live in buffers with a zero border as wide as the largest dilation,
// so a 3x3 conv reads its neighbours without bounds checks. Each conv runs in parallel on oneTBB, in one of two ways:
//  - on CPUs with AVX-512 (checked at run time): a direct convolution kernel, compiled for AVX-512 through
//    function attributes only, so that the rest of the binary (and Eigen, and the standard library) stays
//    plain x86-64. A tile of 12 pixels x 32 output channels is accumulated in 24 registers over the 9 taps
//    and all input channels, from weights packed per 32-channel block; bias, PReLU and the residual add are
//    applied before the store. Rows of the image run in parallel.
//  - otherwise: im2col + Eigen GEMM over strips of rows, the strips in parallel, bias, PReLU and the
//    residual add applied while the strip is still in cache.
// RESIDUE_EIGEN_PORTABLE=1 in the environment forces the second way (for tests and comparisons).
#include <algorithm>
#include <cstdlib>
#include <cstring>

#include <Eigen/Core>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define RESIDUE_HAVE_AVX512_KERNEL 1
#endif

#include "core/nn/backend.h"

namespace residue::nn {
namespace {

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

constexpr int kLanes = 16;  // floats per AVX-512 register
constexpr int kTileBlock = 2;  // output-channel registers per tile (32 channels)
constexpr int kTilePixels = 12;  // pixels per tile: 12 x 2 accumulators, 2 weight registers, 1 broadcast

// A conv ready to run: weights for the Eigen GEMM or blocked for the AVX-512 kernel.
struct PackedConv {
  int in = 0, out = 0;
  RowMatrix weights;          // Eigen: (9 * in) x out, row (ky * 3 + kx) * in + i
  std::vector<float> blocked;  // AVX-512: per block of kTileBlock * 16 output channels, [tap][in][channel]
  std::vector<float> bias;     // `out` values; AVX-512: padded to whole registers with zeros
  std::vector<float> prelu;    // empty: no activation; AVX-512: padded with ones
};

int padded_channels(int out) { return (out + kLanes - 1) / kLanes * kLanes; }

PackedConv pack(const Conv3x3& c, const std::vector<float>& prelu, bool blocked) {
  PackedConv p;
  p.in = c.in;
  p.out = c.out;
  p.bias = c.bias;
  p.bias.resize(static_cast<size_t>(c.out), 0.0f);
  p.prelu = prelu;
  if (!blocked) {
    p.weights.resize(9 * c.in, c.out);
    for (int o = 0; o < c.out; ++o)
      for (int i = 0; i < c.in; ++i)
        for (int ky = 0; ky < 3; ++ky)
          for (int kx = 0; kx < 3; ++kx) p.weights((ky * 3 + kx) * c.in + i, o) = c.w(o, i, ky, kx);
    return p;
  }
  const int padded = padded_channels(c.out);
  p.bias.resize(static_cast<size_t>(padded), 0.0f);
  if (!p.prelu.empty()) p.prelu.resize(static_cast<size_t>(padded), 1.0f);
  p.blocked.assign(static_cast<size_t>(padded) * 9 * static_cast<size_t>(c.in), 0.0f);
  for (int o0 = 0; o0 < padded; o0 += kTileBlock * kLanes) {
    const int n = std::min(kTileBlock * kLanes, padded - o0);  // channels in this block
    float* block = p.blocked.data() + static_cast<size_t>(o0) * 9 * static_cast<size_t>(c.in);
    for (int t = 0; t < 9; ++t)
      for (int i = 0; i < c.in; ++i)
        for (int k = 0; k < n && o0 + k < c.out; ++k)
          block[(static_cast<size_t>(t) * static_cast<size_t>(c.in) + static_cast<size_t>(i)) * static_cast<size_t>(n) +
                static_cast<size_t>(k)] = c.w(o0 + k, i, t / 3, t % 3);
  }
  return p;
}

// An H x W x C image with a zero border of b pixels: pixel (y, x) for y in [-b, H + b), x in [-b, W + b).
struct Padded {
  int64_t h = 0, w = 0, b = 0;
  int c = 0;
  std::vector<float> v;
  void reset(int64_t height, int64_t width, int channels, int64_t border) {
    if (height == h && width == w && channels == c && border == b) return;  // the border is still zero
    h = height;
    w = width;
    c = channels;
    b = border;
    v.assign(static_cast<size_t>((h + 2 * b) * (w + 2 * b) * c), 0.0f);
  }
  int64_t row() const { return (w + 2 * b) * c; }
  float* at(int64_t y, int64_t x) { return v.data() + (y + b) * row() + (x + b) * c; }
  const float* at(int64_t y, int64_t x) const { return v.data() + (y + b) * row() + (x + b) * c; }
};

// Where a conv writes (and where the residual it adds is): pixel (y, x) at data + y * row + x * channels.
struct View {
  float* data = nullptr;
  int64_t row = 0;
  int channels = 0;
  float* at(int64_t y, int64_t x) const { return data + y * row + x * channels; }
};

View view(Padded& p) { return {p.at(0, 0), p.row(), p.c}; }

#ifdef RESIDUE_HAVE_AVX512_KERNEL
// MR pixels x NR registers of output channels. `src`: the input at pixel (y - d, x - d) for dilation d; `w`:
// the block's weights [tap][in][NR * 16]; `dst` and `add` at pixel (y, x), channel o0; `last`: the lanes of
// the last register that are real channels.
template <int MR, int NR>
__attribute__((target("avx512f"))) void tile_avx512(const float* src, int64_t src_row, int cin, int d, const float* w,
                                                    const float* bias, const float* prelu, float* dst,
                                                    const float* add, int dst_c, __mmask16 last) {
  __m512 acc[MR][NR];
  for (int p = 0; p < MR; ++p)
    for (int j = 0; j < NR; ++j) acc[p][j] = _mm512_setzero_ps();
  for (int ky = 0; ky < 3; ++ky)
    for (int kx = 0; kx < 3; ++kx) {
      const float* s = src + ky * d * src_row + kx * d * cin;
      const float* wt = w + (ky * 3 + kx) * cin * NR * kLanes;
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
    const __m512 bv = _mm512_loadu_ps(bias + j * kLanes);
    const __m512 av = prelu ? _mm512_loadu_ps(prelu + j * kLanes) : zero;
    for (int p = 0; p < MR; ++p) {
      __m512 v = _mm512_add_ps(acc[p][j], bv);
      if (prelu) v = _mm512_mask_mul_ps(v, _mm512_cmp_ps_mask(v, zero, _CMP_LT_OQ), v, av);
      if (add) v = _mm512_add_ps(v, _mm512_maskz_loadu_ps(m, add + p * dst_c + j * kLanes));
      _mm512_mask_storeu_ps(dst + p * dst_c + j * kLanes, m, v);
    }
  }
}

// The last pixels of a row (fewer than kTilePixels): the tile for exactly `r` of them.
template <int NR, int MR = 1>
__attribute__((target("avx512f"))) void tile_tail_avx512(int r, const float* src, int64_t src_row, int cin, int d,
                                                         const float* w, const float* bias, const float* prelu,
                                                         float* dst, const float* add, int dst_c, __mmask16 last) {
  if constexpr (MR < kTilePixels) {
    if (r == MR) return tile_avx512<MR, NR>(src, src_row, cin, d, w, bias, prelu, dst, add, dst_c, last);
    tile_tail_avx512<NR, MR + 1>(r, src, src_row, cin, d, w, bias, prelu, dst, add, dst_c, last);
  }
}

template <int NR>
__attribute__((target("avx512f"))) void block_row_avx512(const float* src, int64_t src_row, int cin, int d,
                                                         int64_t width, const float* w, const float* bias,
                                                         const float* prelu, float* dst, const float* add, int dst_c,
                                                         __mmask16 last) {
  int64_t x = 0;
  for (; x + kTilePixels <= width; x += kTilePixels)
    tile_avx512<kTilePixels, NR>(src + x * cin, src_row, cin, d, w, bias, prelu, dst + x * dst_c,
                                 add ? add + x * dst_c : nullptr, dst_c, last);
  if (x < width)
    tile_tail_avx512<NR>(static_cast<int>(width - x), src + x * cin, src_row, cin, d, w, bias, prelu,
                         dst + x * dst_c, add ? add + x * dst_c : nullptr, dst_c, last);
}

// One output row, all output channels. `src` at input pixel (y - d, -d); `dst`, `add` at pixel (y, 0).
__attribute__((target("avx512f"))) void conv_row_avx512(const PackedConv& c, const float* src, int64_t src_row, int d,
                                                        int64_t width, float* dst, const float* add, int dst_c) {
  const int padded = padded_channels(c.out);
  const float* prelu = c.prelu.empty() ? nullptr : c.prelu.data();
  for (int o0 = 0; o0 < padded; o0 += kTileBlock * kLanes) {
    const int regs = std::min(kTileBlock * kLanes, padded - o0) / kLanes;
    const int real = std::min(regs * kLanes, c.out - o0);  // channels of this block that exist
    const int in_last = real - (regs - 1) * kLanes;
    const auto last = static_cast<__mmask16>((1u << in_last) - 1u);
    const float* w = c.blocked.data() + static_cast<size_t>(o0) * 9 * static_cast<size_t>(c.in);
    const float* a = add ? add + o0 : nullptr;
    static_assert(kTileBlock == 2, "block_row_avx512 instances below assume 2 registers per block");
    if (regs == 2)
      block_row_avx512<2>(src, src_row, c.in, d, width, w, c.bias.data() + o0, prelu ? prelu + o0 : nullptr, dst + o0,
                          a, dst_c, last);
    else
      block_row_avx512<1>(src, src_row, c.in, d, width, w, c.bias.data() + o0, prelu ? prelu + o0 : nullptr, dst + o0,
                          a, dst_c, last);
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
  explicit EigenBackend(const Network& n) : arch_(n.arch), avx512_(cpu_has_avx512() && !portable_forced()) {
    head_ = pack(n.head, n.head_prelu, avx512_);
    for (const auto& b : n.blocks) {
      blocks_.push_back(pack(b.conv1, b.prelu, avx512_));
      blocks_.push_back(pack(b.conv2, {}, avx512_));
    }
    tail_ = pack(n.tail, {}, avx512_);
    out_ = pack(n.out, {}, avx512_);
  }

  std::string description() const override { return avx512_ ? "eigen fp32 (avx512 direct)" : "eigen fp32"; }

  size_t scratch_bytes(int64_t width, int64_t height) const override {
    // Three padded activation buffers (head output, block state, temporary), the padded input, and without
    // AVX-512 one im2col strip and its GEMM result per thread.
    const int64_t b = arch_.max_dilation();
    const auto padded = static_cast<size_t>((width + 2 * b) * (height + 2 * b));
    size_t bytes = padded * static_cast<size_t>(3 * arch_.width + arch_.in_channels()) * sizeof(float);
    if (!avx512_) {
      const auto threads = static_cast<size_t>(tbb::this_task_arena::max_concurrency());
      const auto strip = static_cast<size_t>(std::min(kStripPixels, std::max<int64_t>(width, 1) * height));
      bytes += threads * strip * static_cast<size_t>(9 * std::max(arch_.width, arch_.in_channels()) + arch_.width) *
               sizeof(float);
    }
    return bytes;
  }

  void run(const Image& input, Image& output) override {
    const int64_t h = input.height(), w = input.width();
    output = Image(w, h, 3);
    if (h == 0 || w == 0) return;
    const int64_t border = arch_.max_dilation();
    input_.reset(h, w, input.channels(), 1);
    for (int64_t y = 0; y < h; ++y)
      std::memcpy(input_.at(y, 0), input.row(y).data(), static_cast<size_t>(w * input.channels()) * sizeof(float));
    head_out_.reset(h, w, arch_.width, border);
    state_.reset(h, w, arch_.width, border);
    temp_.reset(h, w, arch_.width, border);
    conv(input_, head_, view(head_out_), nullptr, 1);
    std::memcpy(state_.v.data(), head_out_.v.data(), head_out_.v.size() * sizeof(float));
    for (size_t b = 0; b < blocks_.size(); b += 2) {
      const int d = arch_.dilation(static_cast<int>(b / 2));
      conv(state_, blocks_[b], view(temp_), nullptr, d);
      const View s = view(state_);
      conv(temp_, blocks_[b + 1], s, &s, d);  // in place: + identity
    }
    const View head = view(head_out_);
    conv(state_, tail_, view(temp_), &head, 1);
    conv(temp_, out_, {output.data(), w * 3, 3}, nullptr, 1);
    if (arch_.input_skip) add_input_skip(input, output);
  }

 private:
  // out = act(conv(in) + bias) (+ add), taps `d` pixels apart. `out` may alias `add` (the residual), never `in`.
  void conv(const Padded& in, const PackedConv& c, const View& out, const View* add, int d) {
#ifdef RESIDUE_HAVE_AVX512_KERNEL
    if (avx512_) {
      tbb::parallel_for(tbb::blocked_range<int64_t>(0, in.h), [&](const tbb::blocked_range<int64_t>& rows) {
        for (int64_t y = rows.begin(); y < rows.end(); ++y)
          conv_row_avx512(c, in.at(y - d, -d), in.row(), d, in.w, out.at(y, 0), add ? add->at(y, 0) : nullptr,
                          out.channels);
      });
      return;
    }
#endif
    conv_eigen(in, c, out, add, d);
  }

  void conv_eigen(const Padded& in, const PackedConv& c, const View& out, const View* add, int d) {
    const int64_t h = in.h, w = in.w;
    const int64_t rows_per_strip = std::max<int64_t>(1, kStripPixels / std::max<int64_t>(w, 1));
    const int64_t strips = (h + rows_per_strip - 1) / rows_per_strip;
    tbb::parallel_for(int64_t{0}, strips, [&](int64_t s) {
      const int64_t y0 = s * rows_per_strip, y1 = std::min(h, y0 + rows_per_strip);
      const int64_t pixels = (y1 - y0) * w;
      Scratch& scratch = scratch_.local();
      scratch.cols.resize(static_cast<size_t>(pixels * 9 * c.in));
      scratch.result.resize(static_cast<size_t>(pixels * c.out));
      // Patches: for each pixel, the 3x3 neighbourhood's channels (the border supplies the zeros).
      const size_t bytes = static_cast<size_t>(c.in) * sizeof(float);
      for (int64_t y = y0; y < y1; ++y)
        for (int64_t x = 0; x < w; ++x) {
          float* dst = scratch.cols.data() + ((y - y0) * w + x) * 9 * c.in;
          for (int ky = 0; ky < 3; ++ky)
            for (int kx = 0; kx < 3; ++kx, dst += c.in)
              std::memcpy(dst, in.at(y + (ky - 1) * d, x + (kx - 1) * d), bytes);
        }
      Eigen::Map<const RowMatrix> patches(scratch.cols.data(), pixels, 9 * c.in);
      Eigen::Map<RowMatrix> result(scratch.result.data(), pixels, c.out);
      result.noalias() = patches * c.weights;
      for (int64_t p = 0; p < pixels; ++p) {
        const int64_t y = y0 + p / w, x = p % w;
        const float* r = scratch.result.data() + p * c.out;
        const float* a = add ? add->at(y, x) : nullptr;
        float* v = out.at(y, x);
        for (int o = 0; o < c.out; ++o) {
          float value = r[o] + c.bias[static_cast<size_t>(o)];
          if (!c.prelu.empty() && value < 0) value *= c.prelu[static_cast<size_t>(o)];
          if (a) value += a[o];
          v[o] = value;
        }
      }
    });
  }

  struct Scratch {
    std::vector<float> cols, result;
  };

  Architecture arch_;
  bool avx512_ = false;
  PackedConv head_, tail_, out_;
  std::vector<PackedConv> blocks_;
  Padded input_, head_out_, state_, temp_;
  tbb::enumerable_thread_specific<Scratch> scratch_;
};

}  // namespace

std::unique_ptr<Backend> make_eigen_backend(const Network& network) {
  return std::make_unique<EigenBackend>(network);
}

}  // namespace residue::nn
