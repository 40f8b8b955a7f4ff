// The convolutions of the eigen backend (backend_eigen.cpp), ready to run: each conv's weights packed once, as
// Eigen's GEMM reads them (im2col rows: tap, then channel) or, for the direct AVX-512 kernel, blocked per 32
// output channels; and that kernel, one output row at a time. The kernel is compiled for AVX-512 through
// function attributes only, so that the rest of the binary stays plain x86-64; cpu_has_avx512() says whether
// it may run. A tile of 12 pixels x 32 output channels is accumulated in 24 registers over the taps and all
// input channels; bias, the activation and the residual add are applied before the store.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "core/nn/graph.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define RESIDUE_HAVE_AVX512_KERNEL 1
#endif

namespace residue::nn::direct_conv {

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

constexpr int kLanes = 16;       // floats per AVX-512 register
constexpr int kTileBlock = 2;    // output-channel registers per tile (32 channels)
constexpr int kTilePixels = 12;  // pixels per tile: 12 x 2 accumulators, 2 weight registers, 1 broadcast

enum Act { kNone = 0, kRelu = 1, kPrelu = 2 };

inline int padded_channels(int out) { return (out + kLanes - 1) / kLanes * kLanes; }

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

// Packs `op` of `g`: for the direct kernel when `blocked`, else for Eigen's GEMM.
PackedConv pack(const Graph& g, const GraphOp& op, bool blocked);

// Whether this CPU runs the direct kernel.
bool cpu_has_avx512();

#ifdef RESIDUE_HAVE_AVX512_KERNEL
// One output row of one part of `c`, all output channels. `src` at the part's input pixel (y - r, -r) for the
// conv's reach r, rows `src_row` floats apart; `dst` and `add` (a residual, or null) at pixel (y, 0).
void conv_row_avx512(const PackedConv& c, size_t part, const float* src, int64_t src_row, int64_t width, float* dst,
                     int dst_c, const float* add, int add_c);
#endif

}  // namespace residue::nn::direct_conv
