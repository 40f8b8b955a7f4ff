// The residual network of Wong & Wong 2019 (section 3.2), in inference form.
//
//   h   = PReLU(conv3x3_head(x) + b)                      C_in -> W
//   y   = h
//   N x y = y + BN(conv3x3(PReLU(BN(conv3x3(y)))))        ResBlock, identity shortcut, convs without bias
//   y   = BN(conv3x3_tail(y)) + h                          network-wide skip from the head
//   out = conv3x3_out(y) + b                               W -> 3 (log-compressed colour)
//
// 2N + 3 convolutions (35 for the paper's N = 16, W = 128), every one 3x3 with zero 'same' padding, so the
// receptive field reaches 2N + 3 pixels on each side. A variant (not in the paper) dilates the ResBlocks'
// convs (taps d pixels apart, padding d) for a larger receptive field at the same cost: dilations 1,2,4,8
// repeated over 8 blocks reach 63 pixels instead of 19. Another variant adds the input's log colour planes
// to the output ("input skip"): the network then learns the correction to the noisy colour, which is zero
// where the input is already clean, instead of the whole image. Batch norm is folded into the convolutions when a
// model is loaded: every layer below is a conv with bias.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/features/feature_set.h"
#include "core/nn/graph.h"

namespace residue::nn {

struct Architecture {
  int blocks = 16;   // N
  int width = 128;   // W, filters per conv
  FeatureSet features = FeatureSet::Full;
  std::vector<int> dilations;  // per ResBlock, repeated over the blocks; empty: all 1 (the paper)
  bool input_skip = false;     // variant: out += the input's log colour planes (the net predicts the correction)

  int in_channels() const { return feature_channels(features); }
  int conv_layers() const { return 2 * blocks + 3; }
  int dilation(int block) const {
    return dilations.empty() ? 1 : dilations[static_cast<size_t>(block) % dilations.size()];
  }
  int max_dilation() const;
  int halo() const;  // the receptive field's reach: d pixels per 3x3 conv of dilation d
  // Multiply-adds x 2 per output pixel.
  double flops_per_pixel() const;
  std::string to_string() const;  // "16/128 full", "8/32 full dilated 1,2,4,8 input-skip"
};

// A 3x3 convolution with bias. Weights in OIHW order (as PyTorch stores them): weight[((o*in + i)*3 + ky)*3 + kx].
struct Conv3x3 {
  int in = 0;
  int out = 0;
  std::vector<float> weight;
  std::vector<float> bias;  // `out` values
  float w(int o, int i, int ky, int kx) const {
    return weight[static_cast<size_t>(((o * in + i) * 3 + ky) * 3 + kx)];
  }
};

// Batch-norm parameters as trained (inference uses the running statistics).
struct BatchNorm {
  std::vector<float> gamma, beta, mean, var;
  float eps = 1e-5f;
};

// "1,2,4,8": the metadata and command-line form; parse_dilations returns nullopt unless every entry is an
// integer in [1, 64].
std::string dilations_to_string(const std::vector<int>& d);
std::optional<std::vector<int>> parse_dilations(const std::string& text);

// Folds BN into the preceding conv: w' = w * g / sqrt(v + eps), b' = (b - m) * g / sqrt(v + eps) + beta.
Conv3x3 fold_batch_norm(const Conv3x3& conv, const BatchNorm& bn);

struct ResBlock {
  Conv3x3 conv1;              // BN folded
  std::vector<float> prelu;   // one slope per channel
  Conv3x3 conv2;              // BN folded
};

// The network ready for inference (BN folded).
struct Network {
  Architecture arch;
  Conv3x3 head;
  std::vector<float> head_prelu;
  std::vector<ResBlock> blocks;
  Conv3x3 tail;  // BN folded; the head's output is added after it
  Conv3x3 out;
};

// The network as a graph: head, blocks (conv1 -> PReLU -> conv2 + identity, in place), tail + head, out (+ the
// input's colour planes through a 1x1 selection conv for the input-skip variant).
Graph to_graph(const Network& network);

// A network with He-initialised weights, random PReLU slopes and biases: for tests and benchmarks.
Network random_network(const Architecture& arch, uint32_t seed);

}  // namespace residue::nn
