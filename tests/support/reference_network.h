// An independent float64 implementation of the network for tests: naive loops straight from the paper's
// description, with batch norm applied explicitly when given unfolded weights. Slow; use small images.
#pragma once

#include <vector>

#include "core/image/image.h"
#include "core/nn/network.h"

namespace residue::testing {

// A float64 tensor H x W x C (NHWC).
struct Tensor64 {
  int64_t h = 0, w = 0;
  int c = 0;
  std::vector<double> v;
  double& at(int64_t y, int64_t x, int ch) { return v[static_cast<size_t>((y * w + x) * c + ch)]; }
  double at(int64_t y, int64_t x, int ch) const { return v[static_cast<size_t>((y * w + x) * c + ch)]; }
};

Tensor64 to_tensor(const Image& image);

// 3x3 conv with zero 'same' padding and bias, taps `dilation` pixels apart, in float64.
Tensor64 naive_conv3x3(const Tensor64& in, const nn::Conv3x3& conv, int dilation = 1);

// Any graph (graph.h) in float64, op by op in the textbook way: a conv sums over the concatenation of its inputs
// with zeros outside the image, then activation, then residual; pool takes the max of each 2x2 block; upsample
// repeats each pixel 2x2. Returns the output op's value.
Tensor64 naive_graph(const nn::Graph& graph, const Image& input);

// The whole (folded) network in float64.
Tensor64 naive_forward(const nn::Network& net, const Image& input);

// max |a - b| / max(max |b|, floor): the relative error measure the tests bound.
double max_relative_error(const Image& a, const Tensor64& b, double floor = 1e-3);

}  // namespace residue::testing
