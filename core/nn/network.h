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
//
// The multi-scale variant (not in the paper; `levels` set) keeps the paper's blocks, the network-wide skip and
// the direct output, but spreads the ResBlocks over L resolution levels, U-Net fashion, for a receptive field
// of hundreds of pixels at a fraction of the flat network's cost:
//   h = PReLU(conv(x)) at level 0; per level l < L-1: n_l ResBlocks (kept as the skip s_l), then down:
//   PReLU(BN(conv(pool(.)))) into level l+1 (width W_{l+1}); the bottom level: n_{L-1} ResBlocks; back up per
//   level: PReLU(BN(conv(cat(upsample(.), s_l)))) to W_l, n_l ResBlocks; then tail + h and out as above.
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
  // Multi-scale variant: ResBlocks per level (level 0 first; the encoder and the decoder each have that many
  // at levels above the bottom) and each level's width. Empty: the paper's flat network (blocks, width).
  std::vector<int> levels, widths;
  bool demodulate = false;     // variant: colour divided by the albedo in, multiplied back out (core/features)
  // Variant: colour (and prior, noise) multiplied by the image's autoexposure in, divided back out (core/features):
  // a dim render looks to the network like a well-exposed one (issue 16). The exposure maps the image's
  // log-average luminance to `exposure_key` (OIDN's autoexposure: 0.18).
  static constexpr float kOidnExposureKey = 0.18f;
  bool autoexposure = false;
  float exposure_key = kOidnExposureKey;
  // What the colour is multiplied by, given OIDN's autoexposure of the image (its key / log-average luminance).
  float exposure(float oidn_autoexposure) const {
    return autoexposure ? oidn_autoexposure * (exposure_key / kOidnExposureKey) : 1.0f;
  }
  // Post-correction: the model ("oidn") whose output this one refines. Its log colour comes in as 3 more input
  // planes after the feature set's, and input_skip adds those planes instead of the noisy colour. Empty: none.
  std::string prior;
  // Temporal (issue 51): the radius k of the shot's frames it sees. Each neighbour t-k..t-1, t+1..t+k, warped to
  // this frame along the motion (core/temporal/frame_window.h), comes in as 4 more planes after the prior's: its
  // log colour (3) and where it shows the same surface (1). 0: a still's model.
  int temporal = 0;

  bool multiscale() const { return !levels.empty(); }
  int level_width(int l) const { return widths.empty() ? width : widths[static_cast<size_t>(l)]; }

  int in_channels() const { return feature_channels(features) + (prior.empty() ? 0 : 3) + 4 * 2 * temporal; }
  int skip_plane() const { return prior.empty() ? 0 : feature_channels(features); }  // first plane input_skip adds
  int conv_layers() const;
  int dilation(int block) const {
    return dilations.empty() ? 1 : dilations[static_cast<size_t>(block) % dilations.size()];
  }
  int max_dilation() const;
  int halo() const;  // the tiler's halo: the receptive field's reach (d px per 3x3 conv of dilation d at level 0),
                     // rounded up to the alignment
  int alignment() const { return 1 << (multiscale() ? static_cast<int>(levels.size()) - 1 : 0); }
  // Multiply-adds x 2 per output pixel.
  double flops_per_pixel() const;
  std::string to_string() const;  // "16/128 full", "8/32 full dilated 1,2,4,8 input-skip", "ms 2,2,4/32,48,64 full"
  std::string autoexposure_string() const;  // "", " autoexposure" (OIDN's key) or " autoexposure 1"
  // Why these settings cannot go together (a temporal model with a prior, demodulation without an albedo, ...),
  // or nullopt. The one place the rules live: a model file's metadata and the trainer's options are both checked
  // against it.
  std::optional<std::string> contradiction() const;
};

// The network's input planes by name, in order: the feature set's (feature_planes), then a post-correction
// model's prior ("prior.r", ...), then each neighbour's ("t-1.color.r", ..., "t-1.valid", "t+1.color.r", ...).
std::vector<std::string> input_planes(const Architecture& arch);

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
std::string exposure_key_string(float key);  // the metadata form: shortest text that reads back the same float
std::optional<std::vector<int>> parse_dilations(const std::string& text);

// Folds BN into the preceding conv: w' = w * g / sqrt(v + eps), b' = (b - m) * g / sqrt(v + eps) + beta.
Conv3x3 fold_batch_norm(const Conv3x3& conv, const BatchNorm& bn);

struct ResBlock {
  Conv3x3 conv1;              // BN folded
  std::vector<float> prelu;   // one slope per channel
  Conv3x3 conv2;              // BN folded
};

// "2,2,4": the metadata and command-line form of per-level counts; nullopt unless every entry is in [lo, hi].
std::string ints_to_string(const std::vector<int>& v);
std::optional<std::vector<int>> parse_ints(const std::string& text, int lo, int hi);

// A conv (BN folded) followed by a PReLU: the multi-scale network's down and up steps.
struct ConvPRelu {
  Conv3x3 conv;
  std::vector<float> prelu;
};

// One resolution level of a multi-scale network.
struct ScaleLevel {
  std::vector<ResBlock> enc;  // on the way down (the bottom level's only blocks)
  ConvPRelu down;             // above the bottom: pool, then this conv into the next level's width
  ConvPRelu up;               // above the bottom: upsample the level below, concat with enc's output, this conv
  std::vector<ResBlock> dec;  // above the bottom: on the way up
};

// The network ready for inference (BN folded).
struct Network {
  Architecture arch;
  Conv3x3 head;
  std::vector<float> head_prelu;
  std::vector<ResBlock> blocks;    // the flat network's
  std::vector<ScaleLevel> scales;  // the multi-scale network's, level 0 first
  Conv3x3 tail;  // BN folded; the head's output is added after it
  Conv3x3 out;
};

// The network as a graph: head, blocks (conv1 -> PReLU -> conv2 + identity, in place), tail + head, out (+ the
// input's colour planes through a 1x1 selection conv for the input-skip variant).
Graph to_graph(const Network& network);
// The inverse for weights: every conv's weights, bias and slopes taken from the op to_graph names after it in
// `graph` (a fine-tuned copy of to_graph(network)); std::invalid_argument when one is missing or of another size.
void set_weights_from_graph(Network& network, const Graph& graph);

// A network with He-initialised weights, random PReLU slopes and biases: for tests and benchmarks.
Network random_network(const Architecture& arch, uint32_t seed);

}  // namespace residue::nn
