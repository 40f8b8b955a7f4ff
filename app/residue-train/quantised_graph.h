// A model's graph (core/nn/graph.h) as a libtorch module that computes what the onednn int8 plan computes
// (core/nn/graph_plan_onednn.h), for quantisation-aware fine-tuning: every value the plan stores as s8 is rounded
// to its scale (range / 127, saturated to [-128, 127]) where the plan rounds it, and every quantised conv's weights
// to their per-output-channel scale (max |w| / 127 of each input's slice). Where the plan rounds:
//   - the input (its reorder), and every conv's output after its activation and residual;
//   - a concat conv's running sum after each of its parts but the last (the later parts accumulate into s8);
//   - a per-channel PReLU's input (it runs on the conv's s8 output, in place).
// A pool or an upsample moves its source's quanta (no rounding); the values the plan keeps in f32 (the output,
// the convs the output reads, the input skip) are not rounded, and a conv that reads only f32 values (or the
// caller's input) runs on the real values. Rounding passes gradients straight through (inside the range; none
// outside), and each range is learnt (the gradient of LSQ, Esser et al. 2020, through log range).
#pragma once

#include <vector>

#include <torch/torch.h>

#include "core/nn/graph.h"

namespace residue::train {

struct QuantisedGraphImpl : torch::nn::Module {
  // `graph`'s weights (BN folded, as core runs them) become parameters; `ranges` (one per op, as a calibration
  // holds them) are the starting ranges of the values the plan quantises. Throws Error(Usage) for an op the plan
  // could not quantise (an add) or a quantised value with no range.
  QuantisedGraphImpl(const nn::Graph& graph, const std::vector<float>& ranges);

  // x: N x C x H x W feature planes -> the graph's output; `quantised` false: the float network (the same as
  // core's fp32 result). `largest`: raised to each op's largest |value| (one per op).
  torch::Tensor forward(const torch::Tensor& x, bool quantised = true, std::vector<float>* largest = nullptr);
  // Only the ops `rounded` marks (one flag per op) round their value and, for a conv, its weights: the rest runs
  // as the float network does (a study of what each value's 8 bits cost).
  torch::Tensor forward(const torch::Tensor& x, const std::vector<bool>& rounded);
  // Whether op i rounds a value of its own (the input, a quantised conv; a pool or upsample moves its source's).
  bool rounds(int i) const { return rounds(ops_[static_cast<size_t>(i)]); }
  int size() const { return static_cast<int>(ops_.size()); }

  // The weights, biases and slopes as trained, written into `graph`'s ops, and each op's range as the
  // calibration file keeps it (a pool's or an upsample's: its source's; 0 for the values kept in f32).
  void write_to(nn::Graph& graph) const;
  std::vector<float> ranges() const;

  // The parameters split for the optimiser: the ranges learn at their own rate.
  std::vector<torch::Tensor> weight_parameters() const;
  std::vector<torch::Tensor> range_parameters() const;

 private:
  struct Op {
    nn::OpKind kind;
    std::vector<int> inputs;
    int residual = -1;
    int kernel = 3, dilation = 1;
    bool quantised = false;   // its value is stored as s8
    bool float_conv = false;  // a conv that runs on real values (all its inputs f32 or the caller's input)
    nn::Activation activation = nn::Activation::None;
    bool separate_prelu = false;  // per-channel slopes: applied to the rounded conv output
    std::vector<int64_t> part_channels;
    torch::Tensor weight, bias, slopes, log_range;  // conv: OIHW, [O], [O]; quantised: 0-d log of the range
  };
  static bool rounds(const Op& op) { return op.quantised && (op.kind == nn::OpKind::Input || op.kind == nn::OpKind::Conv); }
  torch::Tensor round_value(const Op& op, const torch::Tensor& v) const;
  torch::Tensor run(const torch::Tensor& x, const std::vector<bool>* rounded, std::vector<float>* largest);
  std::vector<Op> ops_;
  int output_ = 0;
};
TORCH_MODULE(QuantisedGraph);

}  // namespace residue::train
