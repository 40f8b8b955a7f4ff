#include "quantised_graph.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/nn/graph_plan_onednn.h"
#include "core/util/error.h"

namespace residue::train {

namespace F = torch::nn::functional;
using nn::Activation;
using nn::OpKind;

namespace {

// x rounded to multiples of `scale` and saturated as s8 holds them; the rounding's gradient passes straight
// through inside the range, so d/dx is 1 there and 0 outside, and d/dscale is LSQ's (round(x/s) - x/s inside,
// the bound outside).
torch::Tensor fake_quantise(const torch::Tensor& x, const torch::Tensor& scale) {
  const torch::Tensor q = torch::clamp(x / scale, -128.0, 127.0);
  return (q + (torch::round(q) - q).detach()) * scale;
}

// Per output channel (dim 0), max |w| / 127 as the plan computes it from the weights it is given (a channel of
// zeros keeps scale 1). Not learnt: the plan derives it from the weights, so it follows them.
torch::Tensor fake_quantise_weight(const torch::Tensor& w) {
  torch::Tensor m = std::get<0>(w.detach().abs().flatten(1).max(1));
  const torch::Tensor scale = torch::where(m > 0, m / 127.0, torch::ones_like(m)).view({-1, 1, 1, 1});
  const torch::Tensor q = w / scale;
  return (q + (torch::round(q) - q).detach()) * scale;
}

torch::Tensor to_tensor(const std::vector<float>& v, std::vector<int64_t> shape) {
  return torch::from_blob(const_cast<float*>(v.data()), shape, torch::kFloat32).clone();
}

}  // namespace

QuantisedGraphImpl::QuantisedGraphImpl(const nn::Graph& graph, const std::vector<float>& ranges) {
  if (ranges.size() != static_cast<size_t>(graph.size()))
    throw Error(ErrorKind::Usage, "quantisation-aware training: " + std::to_string(ranges.size()) + " ranges for a graph of " +
                                      std::to_string(graph.size()) + " ops");
  // Which values the plan stores as s8: the plan's own rule (int8_scales), on a copy carrying the ranges.
  nn::Graph ranged = graph;
  for (int i = 0; i < graph.size(); ++i) ranged.set_range(i, ranges[static_cast<size_t>(i)]);
  const std::vector<float> scales = nn::onednn::int8_scales(ranged);
  output_ = graph.output();
  for (int i = 0; i < graph.size(); ++i) {
    const nn::GraphOp& g = graph.op(i);
    Op op;
    op.kind = g.kind;
    op.inputs = g.inputs;
    op.residual = g.residual;
    op.quantised = scales[static_cast<size_t>(i)] > 0;
    const std::string tag = std::to_string(i);
    if (g.kind == OpKind::Add)
      throw Error(ErrorKind::Usage, "quantisation-aware training: op " + g.name + " is an add, which no Residue "
                                    "model has and this trainer does not model");
    if (g.kind == OpKind::Conv) {
      op.kernel = g.kernel;
      op.dilation = g.dilation;
      op.activation = g.activation;
      op.float_conv = !op.quantised;
      for (int v : g.inputs) {
        op.part_channels.push_back(graph.op(v).channels);
        if (graph.op(v).kind != OpKind::Input && scales[static_cast<size_t>(v)] > 0) op.float_conv = false;
      }
      const bool uniform = std::all_of(g.slopes.begin(), g.slopes.end(), [&](float a) { return a == g.slopes.front(); });
      op.separate_prelu = g.activation == Activation::PReLU && !uniform;
      // The input skip (a float conv other than the output: the colour planes selected) is fixed, not learnt.
      const bool fixed = op.float_conv && i != graph.output();
      op.weight = register_parameter("w" + tag, to_tensor(g.weight, {g.channels, g.in_channels, g.kernel, g.kernel}), !fixed);
      op.bias = register_parameter("b" + tag, to_tensor(g.bias, {g.channels}), !fixed);
      if (g.activation == Activation::PReLU)
        op.slopes = register_parameter("a" + tag, to_tensor(g.slopes, {g.channels}), !fixed);
    }
    if (rounds(op)) {
      const float r = ranges[static_cast<size_t>(i)];
      if (!(r > 0) || !std::isfinite(r))
        throw Error(ErrorKind::Usage, "quantisation-aware training: value " + g.name + " (op " + tag + ") has no range");
      op.log_range = register_parameter("r" + tag, torch::full({}, std::log(r), torch::kFloat32));
    }
    ops_.push_back(std::move(op));
  }
}

torch::Tensor QuantisedGraphImpl::round_value(const Op& op, const torch::Tensor& v) const {
  return fake_quantise(v, torch::exp(op.log_range) / 127.0);
}

torch::Tensor QuantisedGraphImpl::forward(const torch::Tensor& x, bool quantised, std::vector<float>* largest) {
  const std::vector<bool> all(ops_.size(), true);
  return run(x, quantised ? &all : nullptr, largest);
}

torch::Tensor QuantisedGraphImpl::forward(const torch::Tensor& x, const std::vector<bool>& rounded) {
  if (rounded.size() != ops_.size())
    throw Error(ErrorKind::Usage, "QuantisedGraph::forward: " + std::to_string(rounded.size()) + " flags for " +
                                      std::to_string(ops_.size()) + " ops");
  return run(x, &rounded, nullptr);
}

torch::Tensor QuantisedGraphImpl::run(const torch::Tensor& x, const std::vector<bool>* rounded, std::vector<float>* largest) {
  std::vector<torch::Tensor> values(ops_.size());
  torch::Tensor input_rounded;
  for (size_t i = 0; i < ops_.size(); ++i) {
    const Op& op = ops_[i];
    const bool q = rounded && (*rounded)[i] && op.quantised;
    auto in = [&](int v) -> const torch::Tensor& { return values[static_cast<size_t>(v)]; };
    switch (op.kind) {
      case OpKind::Input:
        values[i] = x;
        if (q) input_rounded = round_value(op, x);
        break;
      case OpKind::Conv: {
        const bool quantised_weights = rounded && (*rounded)[i] && !op.float_conv;
        torch::Tensor acc;
        int64_t first = 0;
        for (size_t k = 0; k < op.inputs.size(); ++k) {
          const int v = op.inputs[k];
          const torch::Tensor& src = ops_[static_cast<size_t>(v)].kind == OpKind::Input && !op.float_conv && input_rounded.defined()
                                         ? input_rounded
                                         : in(v);
          torch::Tensor w = op.weight.narrow(1, first, op.part_channels[k]);
          first += op.part_channels[k];
          if (quantised_weights) w = fake_quantise_weight(w);
          const torch::Tensor part =
              F::conv2d(src, w, F::Conv2dFuncOptions().bias(k == 0 ? op.bias : torch::Tensor())
                                    .padding(op.dilation * (op.kernel / 2)).dilation(op.dilation));
          acc = k == 0 ? part : acc + part;
          if (q && k + 1 < op.inputs.size()) acc = round_value(op, acc);
        }
        if (op.activation == Activation::ReLU) acc = torch::relu(acc);
        if (op.activation == Activation::PReLU) {
          if (q && op.separate_prelu) acc = round_value(op, acc);
          acc = torch::prelu(acc, op.slopes);
        }
        if (op.residual >= 0) acc = acc + in(op.residual);
        values[i] = q ? round_value(op, acc) : acc;
        break;
      }
      case OpKind::Pool:
        values[i] = F::max_pool2d(in(op.inputs[0]), F::MaxPool2dFuncOptions(2).stride(2));
        break;
      case OpKind::Upsample:
        values[i] = F::interpolate(in(op.inputs[0]), F::InterpolateFuncOptions()
                                                         .scale_factor(std::vector<double>{2.0, 2.0})
                                                         .mode(torch::kNearest));
        break;
      case OpKind::Add:
        break;  // refused by the constructor
    }
    if (largest) (*largest)[i] = std::max((*largest)[i], values[i].detach().abs().max().item<float>());
  }
  return values[static_cast<size_t>(output_)];
}

std::vector<float> QuantisedGraphImpl::ranges() const {
  std::vector<float> r(ops_.size(), 0.0f);
  for (size_t i = 0; i < ops_.size(); ++i) {
    const Op& op = ops_[i];
    if (op.log_range.defined()) r[i] = std::exp(op.log_range.item<float>());
    else if ((op.kind == OpKind::Pool || op.kind == OpKind::Upsample) && op.quantised)
      r[i] = r[static_cast<size_t>(op.inputs[0])];  // it carries its source's quanta
  }
  return r;
}

void QuantisedGraphImpl::write_to(nn::Graph& graph) const {
  auto values = [](const torch::Tensor& t) {
    const torch::Tensor c = t.detach().contiguous().to(torch::kFloat32);
    return std::vector<float>(c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
  };
  for (size_t i = 0; i < ops_.size(); ++i) {
    const Op& op = ops_[i];
    if (op.kind != OpKind::Conv) continue;
    graph.set_conv_parameters(static_cast<int>(i), values(op.weight), values(op.bias),
                              op.slopes.defined() ? values(op.slopes) : std::vector<float>{});
  }
  const std::vector<float> r = ranges();
  for (size_t i = 0; i < r.size(); ++i) graph.set_range(static_cast<int>(i), r[i]);
}

std::vector<torch::Tensor> QuantisedGraphImpl::weight_parameters() const {
  std::vector<torch::Tensor> p;
  for (const Op& op : ops_)
    for (const torch::Tensor* t : {&op.weight, &op.bias, &op.slopes})
      if (t->defined() && t->requires_grad()) p.push_back(*t);
  return p;
}

std::vector<torch::Tensor> QuantisedGraphImpl::range_parameters() const {
  std::vector<torch::Tensor> p;
  for (const Op& op : ops_)
    if (op.log_range.defined()) p.push_back(op.log_range);
  return p;
}

}  // namespace residue::train
