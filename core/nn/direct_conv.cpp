#include "core/nn/direct_conv.h"

#include <algorithm>

#ifdef RESIDUE_HAVE_AVX512_KERNEL
#include <immintrin.h>
#endif

namespace residue::nn::direct_conv {

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

#ifdef RESIDUE_HAVE_AVX512_KERNEL
namespace {

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

}  // namespace

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


}  // namespace residue::nn::direct_conv
