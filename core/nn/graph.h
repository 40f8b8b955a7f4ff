// The network as a small graph of ops: what every backend runs.
//
// Ops (each produces one value, NHWC, at a resolution level: 0 = the tile, k = 1/2^k of it):
//   Input     the feature planes of the tile
//   Conv      KxK (K = 1 or 3) conv with bias over the channel concatenation of its inputs (OIDN's
//             "concat conv": cat(a, b) feeding a conv is one op, so no concatenated copy is ever made),
//             zero 'same' padding, taps `dilation` pixels apart, then an activation (none, ReLU, PReLU),
//             then optionally + a residual value (the ResNet's identity shortcut and network-wide skip)
//   Pool      2x2 max pool, stride 2 (level + 1)
//   Upsample  2x nearest (level - 1)
//   Add       elementwise sum of two values of one shape
// Ops are kept in topological order (every op's inputs come before it), which is also the order they run.
//
// From the graph, never hand-written: the tile alignment (2^deepest level: 16 for OIDN's four pools), the
// receptive field's reach (how far an output pixel sees, in tile pixels, which the tiler's halo must cover
// for tiled output to equal untiled), FLOPs per pixel, and what each value's consumers need (conv borders).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/image/image.h"

namespace residue::nn {

enum class OpKind { Input, Conv, Pool, Upsample, Add };
enum class Activation { None, ReLU, PReLU };

struct GraphOp {
  OpKind kind = OpKind::Input;
  std::string name;
  std::vector<int> inputs;  // Conv: 1+ sources concatenated (first input's channels first); Pool/Upsample 1; Add 2
  int residual = -1;        // Conv: a value added after the activation (same channels and level); -1: none
  int channels = 0;         // output channels
  int level = 0;            // resolution level of the output
  // Conv only.
  int kernel = 3;  // 1 or 3
  int dilation = 1;
  int in_channels = 0;  // the sum of the inputs' channels
  std::vector<float> weight;  // OIHW: [channels][in_channels][kernel][kernel]
  std::vector<float> bias;    // `channels` values
  Activation activation = Activation::None;
  std::vector<float> slopes;  // PReLU: one per channel
  // Every op: the largest |value| its output took on the model's calibration set (model_file.h), which int8
  // inference quantises it by; 0: not calibrated.
  float range = 0.0f;

  float w(int o, int i, int ky, int kx) const {
    return weight[static_cast<size_t>(((o * in_channels + i) * kernel + ky) * kernel + kx)];
  }
};

class Graph {
 public:
  // Builders return the new op's index. They check shapes and throw std::invalid_argument on a bad graph.
  int input(int channels);
  int conv(std::string name, std::vector<int> inputs, int out_channels, int kernel, std::vector<float> weight,
           std::vector<float> bias, Activation activation, std::vector<float> slopes = {}, int dilation = 1,
           int residual = -1);
  int pool(int x);
  int upsample(int x);
  int add(int a, int b);
  void set_output(int x);  // default: the last op added
  void set_range(int x, float range) { ops_[static_cast<size_t>(x)].range = range; }  // calibration.h
  // New weights (OIHW), bias and PReLU slopes for conv x, of the sizes it has (fine-tuning: residue-train's
  // quantisation-aware training); std::invalid_argument otherwise.
  void set_conv_parameters(int x, std::vector<float> weight, std::vector<float> bias, std::vector<float> slopes);

  const std::vector<GraphOp>& ops() const { return ops_; }
  const GraphOp& op(int i) const { return ops_[static_cast<size_t>(i)]; }
  int size() const { return static_cast<int>(ops_.size()); }
  int output() const { return output_ >= 0 ? output_ : size() - 1; }
  int input_channels() const;
  int output_channels() const { return ops_.empty() ? 0 : op(output()).channels; }

  int max_level() const;
  // Tile width and height must be multiples of this (2^max_level); so must the tile's origin in the image.
  int alignment() const { return 1 << max_level(); }
  // Throws residue::Error when a tile cannot run: Input for the wrong number of planes, Usage for a width or
  // height off the alignment.
  void check_tile(const Image& input) const;
  // How far (tile pixels) an output pixel's value reaches into the input, beyond its own footprint.
  int receptive_reach() const;
  // The tiler's halo: the reach rounded up to the alignment, so tiles with halo stay on the pooling grid.
  int halo() const;
  // Multiply-adds x 2 per input pixel (a value at level k counts 1/4^k of a pixel).
  double flops_per_pixel() const;
  // For each op, the part of its value (in its level's pixels, within an h x w tile) that the `needed` part of the
  // output depends on: a conv needs its taps' reach around what is needed of it, a pool the 2x2 blocks, an
  // upsample the source pixels; empty where nothing needed reads the value. A UNet's decoder needs a few pixels
  // around the tile's core, not the whole halo, so a backend computing only these regions skips most of it.
  std::vector<Rect> needed_regions(int64_t h, int64_t w, const Rect& needed) const;
  // For each op, the last op that reads its value (-1: none, i.e. the output).
  std::vector<int> last_uses() const;
  // For each op, the zero border its value needs for the convs that read it: max dilation * (kernel / 2).
  std::vector<int> borders() const;
  std::string summary() const;  // "31 ops: 16 conv, 4 pool, 4 upsample; 4 levels"

 private:
  int push(GraphOp op);
  void check_value(int x, const char* what) const;
  std::vector<GraphOp> ops_;
  int output_ = -1;
};

}  // namespace residue::nn
