// The oneDNN backend's plan of one tile size (backend_onednn.cpp): a oneDNN primitive per op of a Graph, every
// value's layout as oneDNN picks it for its readers, and every value placed in one arena (arena.h).
// Each conv's output takes the layout oneDNN picks for it (format_tag::any: nChw16c or nhwc on AVX-512) and its
// readers take that layout as is, so no reorder runs between layers; only the input (f32 nhwc -> the first
// conv's source layout / bf16) and the output are reordered, and only when they differ. Fused into the convs:
// the bias, ReLU and uniform PReLU (eltwise post-op), the residual add (a `sum` post-op after the activation:
// the conv accumulates into the value it overwrites in place; a residual still needed later is copied into the
// output first). A concat conv runs one primitive per input, the later ones accumulating into the first one's
// output, the activation on the last. PReLU with per-channel slopes runs as a separate in-place prelu
// primitive after its conv (oneDNN 2.6's prelu post-op has no optimised convolution).
//
// int8: every value is s8 with a scale of its own (its calibrated range / 127: int8_scales), shared by the values
// oneDNN moves unscaled (a pool's or an upsample's source, an add's inputs); weights s8 with a scale per output
// channel; each conv's output scales, s_src * s_weight[o] / s_dst, its bias in accumulator units, its residual
// rescaled by its sum post-op (s_residual / s_dst, so a conv may still overwrite its residual in place). The
// input is quantised by its reorder. Kept in f32: the output and the convs it reads (the last layer's features)
// and the input skip (a conv reading only the input whose value is the output's residual: the render's colour
// carried to the output); a conv whose inputs are all f32 runs in f32, from the caller's input where it reads it.
#pragma once

#include <cstdint>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <dnnl.hpp>

#include "core/nn/arena.h"
#include "core/nn/backend.h"
#include "core/nn/graph.h"

namespace residue::nn::onednn {

// One input of a conv: its slice of the weights (OIHW), reordered on first use into each layout asked for.
struct ConvPart {
  int value = 0;
  int in = 0;
  std::vector<float> weight;
  std::vector<float> weight_scale;  // int8: per output channel, max |w| / 127
  std::vector<std::pair<dnnl::memory::desc, dnnl::memory>> packed;
};

struct ConvLayer {
  std::vector<ConvPart> parts;
  dnnl::memory bias;    // f32 {out}
  dnnl::memory zeros;   // f32 {out}: the later parts' bias
  dnnl::memory bias_int8;  // int8: the bias in the first part's accumulator units (made on first use)
  dnnl::memory slopes;  // f32 {1, out, 1, 1}: per-channel PReLU (a separate primitive); empty otherwise
  bool fused_act = false;       // ReLU or uniform PReLU as an eltwise post-op
  bool separate_prelu = false;  // per-channel PReLU: `slopes` set
  float alpha = 0.0f;
};

// Where a primitive reads or writes: a value of the graph (its place in the arena), or the caller's buffers.
struct Binding {
  int arg = 0;
  int value = -1;     // op index; -1 with the flags below
  bool user_input = false, user_output = false;
};

struct Step {
  dnnl::primitive primitive;
  std::vector<Binding> bindings;
  std::unordered_map<int, dnnl::memory> fixed;  // weights, bias, slopes
  dnnl::memory::desc scratchpad;
  int residual_copy_for = -1;  // a copy of conv N's residual into its output, dropped when N runs in place
  std::string label, impl;     // the op and oneDNN's implementation (for RESIDUE_PROFILE)
};

struct Plan {
  std::vector<dnnl::memory::desc> values;  // per op: the layout of its output
  dnnl::memory::desc user_in, user_out;
  bool input_direct = false;   // the input value is the caller's buffer (no reorder)
  bool output_direct = false;  // the output value is the caller's buffer
  ArenaPlan arena;
  size_t scratchpad = 0;
  std::vector<Step> steps;
  std::string impl;  // the implementation of the costliest conv
};

// A conv's layer: its weights per input (OIHW), bias and activation, as oneDNN will take them.
ConvLayer make_layer(const Graph& graph, const GraphOp& op, const dnnl::engine& engine);

// int8: each value's scale (real value = quantum x scale), 0 for the values kept in f32 (the output, the input
// skip). Error(Usage) when a value that is quantised has no calibrated range (GraphOp::range).
std::vector<float> int8_scales(const Graph& graph);

// The plan of an h x w tile: primitives in order and the arena. Primitives are made for the OpenMP thread
// count in force. Weights are reordered into the layouts the plan asks for on first use (kept in `layers`).
Plan make_plan(const Graph& graph, std::vector<ConvLayer>& layers, Precision precision, const dnnl::engine& engine,
               dnnl::stream& stream, int64_t h, int64_t w);

}  // namespace residue::nn::onednn
