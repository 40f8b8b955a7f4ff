#include "core/nn/graph_plan_onednn.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <numeric>

#include "core/util/error.h"

namespace residue::nn::onednn {
namespace {

using dt = dnnl::memory::data_type;
using tag = dnnl::memory::format_tag;
using dims = dnnl::memory::dims;

dnnl::memory::dims nchw(int64_t c, int64_t h, int64_t w) { return {1, c, h, w}; }

class Planner {
 public:
  Planner(const Graph& graph, std::vector<ConvLayer>& layers, Precision precision, const dnnl::engine& engine,
          dnnl::stream& stream)
      : graph_(graph), layers_(layers), precision_(precision), engine_(engine), stream_(stream) {
    if (precision_ == Precision::INT8) scales_ = int8_scales(graph_);
  }

  Plan plan(int64_t h, int64_t w) {
    Plan p;
    const int n = graph_.size();
    p.values.resize(static_cast<size_t>(n));
    p.user_in = dnnl::memory::desc(nchw(graph_.input_channels(), h, w), dt::f32, tag::nhwc);
    p.user_out = dnnl::memory::desc(nchw(graph_.output_channels(), h, w), dt::f32, tag::nhwc);
    auto dims_of = [&](int i) {
      const GraphOp& o = graph_.op(i);
      return nchw(o.channels, h >> o.level, w >> o.level);
    };
    auto out_type = [&](int i) { return value_type(i); };
    // Steps are made in two passes: descriptors first (they fix every value's layout and size), then, once the
    // arena is planned, nothing else is needed: bindings name values, resolved at run time.
    double costliest = -1;
    for (int i = 0; i < n; ++i) {
      const GraphOp& op = graph_.op(i);
      const auto u = static_cast<size_t>(i);
      switch (op.kind) {
        case OpKind::Input: {
          // The layout the first conv reading the input prefers.
          dnnl::memory::desc chosen = dnnl::memory::desc(dims_of(i), act_type(), tag::nhwc);
          for (int j = i + 1; j < n; ++j) {
            const GraphOp& c = graph_.op(j);
            if (c.kind != OpKind::Conv || c.inputs.front() != i || float_conv(j)) continue;
            chosen = conv_pd(j, 0, dnnl::memory::desc(dims_of(i), act_type(), tag::any),
                             dnnl::memory::desc(dims_of(j), out_type(j), tag::any), false, true, false)
                         .src_desc();
            break;
          }
          p.values[u] = chosen;
          p.input_direct = chosen == p.user_in;
          if (!p.input_direct)
            add_reorder(p, p.user_in, chosen, {DNNL_ARG_FROM, -1, true, false}, {DNNL_ARG_TO, i}, 1.0f / scale(i));
          break;
        }
        case OpKind::Conv: {
          const ConvLayer& l = layers_[u];
          const bool residual = op.residual >= 0;
          dnnl::memory::desc dst = residual ? p.values[static_cast<size_t>(op.residual)]
                                            : dnnl::memory::desc(dims_of(i), out_type(i), tag::any);
          if (residual && dst.data_type() != out_type(i)) dst = dnnl::memory::desc(dims_of(i), out_type(i), tag::any);
          const bool prelu_separate = l.separate_prelu;
          if (prelu_separate && residual)
            throw Error(ErrorKind::Usage, "conv " + op.name + ": per-channel PReLU followed by a residual add is not "
                                          "supported by the onednn backend; use --backend eigen");
          const bool sum_residual = residual && !prelu_separate;
          for (size_t k = 0; k < l.parts.size(); ++k) {
            const ConvPart& part = l.parts[k];
            const bool first = k == 0, last = k + 1 == l.parts.size();
            // A float conv in int8 reads the caller's f32 input, not its quantised copy.
            const bool from_user_input = float_conv(i) && graph_.op(part.value).kind == OpKind::Input;
            const auto pd = conv_pd(i, k, from_user_input ? p.user_in : p.values[static_cast<size_t>(part.value)], dst,
                                    !first, last, last && sum_residual);
            if (first) {
              dst = pd.dst_desc();
              p.values[u] = dst;
              // A residual read again later cannot be overwritten: it is copied into this op's output first
              // (the copy is dropped below where the arena plan lets the conv run in place). In int8 the copy
              // keeps the residual's quanta (the sum rescales them), or its real values in an f32 output.
              if (residual) {
                const float rescale = dst.data_type() == dt::f32 ? scale(op.residual) : 1.0f;
                add_reorder(p, p.values[static_cast<size_t>(op.residual)], dst, {DNNL_ARG_FROM, op.residual},
                            {DNNL_ARG_TO, i}, rescale);
                p.steps.back().residual_copy_for = i;
              }
            }
            const double cost = static_cast<double>(op.channels) * part.in * op.kernel * op.kernel / (1 << (2 * op.level));
            if (cost > costliest) {
              costliest = cost;
              p.impl = pd.impl_info_str();
            }
            p.scratchpad = std::max(p.scratchpad, pd.scratchpad_desc().get_size());
            const Binding src = from_user_input ? Binding{DNNL_ARG_SRC, -1, true, false} : Binding{DNNL_ARG_SRC, part.value};
            p.steps.push_back({dnnl::convolution_forward(pd),
                               {src, {DNNL_ARG_DST, i}},
                               {{DNNL_ARG_WEIGHTS, packed_weights(i, k, pd.weights_desc())},
                                {DNNL_ARG_BIAS, first ? bias_of(i) : l.zeros}},
                               pd.scratchpad_desc()});
            label(p.steps.back(), op.name);
          }
          if (prelu_separate) {
            const dnnl::prelu_forward::desc d(dnnl::prop_kind::forward_inference, dst, l.slopes.get_desc());
            const dnnl::prelu_forward::primitive_desc pd(d, user_scratchpad(), engine_);
            p.scratchpad = std::max(p.scratchpad, pd.scratchpad_desc().get_size());
            p.steps.push_back({dnnl::prelu_forward(pd), {{DNNL_ARG_SRC, i}, {DNNL_ARG_DST, i}},  // in place
                               {{DNNL_ARG_WEIGHTS, l.slopes}}, pd.scratchpad_desc()});
            label(p.steps.back(), op.name + " prelu");
          }
          break;
        }
        case OpKind::Pool: {
          const int x = op.inputs[0];
          const dnnl::pooling_forward::desc d(dnnl::prop_kind::forward_inference, dnnl::algorithm::pooling_max,
                                              p.values[static_cast<size_t>(x)],
                                              dnnl::memory::desc(dims_of(i), out_type(i), tag::any), {2, 2}, {2, 2},
                                              {0, 0}, {0, 0});
          const dnnl::pooling_forward::primitive_desc pd(d, user_scratchpad(), engine_);
          p.values[u] = pd.dst_desc();
          p.scratchpad = std::max(p.scratchpad, pd.scratchpad_desc().get_size());
          p.steps.push_back({dnnl::pooling_forward(pd), {{DNNL_ARG_SRC, x}, {DNNL_ARG_DST, i}}, {}, pd.scratchpad_desc()});
          label(p.steps.back(), op.name);
          break;
        }
        case OpKind::Upsample: {
          const int x = op.inputs[0];
          const dnnl::resampling_forward::desc d(dnnl::prop_kind::forward_inference, dnnl::algorithm::resampling_nearest,
                                                 p.values[static_cast<size_t>(x)],
                                                 dnnl::memory::desc(dims_of(i), out_type(i), tag::any));
          const dnnl::resampling_forward::primitive_desc pd(d, user_scratchpad(), engine_);
          p.values[u] = pd.dst_desc();
          p.scratchpad = std::max(p.scratchpad, pd.scratchpad_desc().get_size());
          p.steps.push_back({dnnl::resampling_forward(pd), {{DNNL_ARG_SRC, x}, {DNNL_ARG_DST, i}}, {}, pd.scratchpad_desc()});
          label(p.steps.back(), op.name);
          break;
        }
        case OpKind::Add:
          add_binary(p, op.inputs[0], op.inputs[1], i, dnnl::memory::desc(dims_of(i), out_type(i), tag::any));
          break;
      }
    }
    const int out = graph_.output();
    p.output_direct = p.values[static_cast<size_t>(out)] == p.user_out;
    if (!p.output_direct) add_reorder(p, p.values[static_cast<size_t>(out)], p.user_out, {DNNL_ARG_FROM, out}, {DNNL_ARG_TO, -1, false, true});

    std::vector<size_t> bytes(static_cast<size_t>(n), 0);
    for (int i = 0; i < n; ++i) bytes[static_cast<size_t>(i)] = p.values[static_cast<size_t>(i)].get_size();
    for (int i = 0; i < n; ++i)
      if (graph_.op(i).kind == OpKind::Input && p.input_direct) bytes[static_cast<size_t>(i)] = 0;
    if (p.output_direct) bytes[static_cast<size_t>(out)] = 0;
    p.arena = plan_arena(graph_, bytes);
    std::erase_if(p.steps, [&](const Step& s) {
      return s.residual_copy_for >= 0 && p.arena.in_place[static_cast<size_t>(s.residual_copy_for)] >= 0;
    });
    return p;
  }


 private:
  dt act_type() const {
    return precision_ == Precision::BF16 ? dt::bf16 : precision_ == Precision::INT8 ? dt::s8 : dt::f32;
  }
  bool int8() const { return precision_ == Precision::INT8; }
  // int8: a value's scale; 1 where it is not quantised (the output, the input skip, other precisions).
  float scale(int value) const {
    return int8() && scales_[static_cast<size_t>(value)] > 0 ? scales_[static_cast<size_t>(value)] : 1.0f;
  }
  dt value_type(int i) const {
    if (int8()) return scales_[static_cast<size_t>(i)] > 0 ? dt::s8 : dt::f32;
    return i == graph_.output() ? dt::f32 : act_type();
  }
  // An int8 plan's conv that runs in f32: its value is kept in f32 (int8_scales) and so is everything it reads
  // (the caller's f32 input for the input op): the output conv and the input skip.
  bool float_conv(int i) const {
    if (!int8() || graph_.op(i).kind != OpKind::Conv || scales_[static_cast<size_t>(i)] > 0) return false;
    for (int v : graph_.op(i).inputs)
      if (graph_.op(v).kind != OpKind::Input && scales_[static_cast<size_t>(v)] > 0) return false;
    return true;
  }

  // The bias a conv's first part adds: in int8, in its accumulator's units (bias / (s_src s_weight[o])).
  dnnl::memory bias_of(int i) {
    ConvLayer& l = layers_[static_cast<size_t>(i)];
    if (!int8() || float_conv(i)) return l.bias;
    if (!l.bias_int8) {
      const GraphOp& op = graph_.op(i);
      const ConvPart& part = l.parts.front();
      l.bias_int8 = dnnl::memory({{op.channels}, dt::f32, tag::a}, engine_);
      auto* b = static_cast<float*>(l.bias_int8.get_data_handle());
      for (int o = 0; o < op.channels; ++o)
        b[o] = op.bias[static_cast<size_t>(o)] / (scale(part.value) * part.weight_scale[static_cast<size_t>(o)]);
    }
    return l.bias_int8;
  }

  static dnnl::primitive_attr user_scratchpad(dnnl::post_ops ops = {}) {
    dnnl::primitive_attr attr;
    attr.set_post_ops(ops);
    attr.set_scratchpad_mode(dnnl::scratchpad_mode::user);
    return attr;
  }

  // Part `k` of conv `i`: `accumulate` adds what dst holds (sum post-op) before the activation; `residual` adds it
  // after; `act` applies the fused activation. int8: output scales per channel, s_src * s_weight[o] / s_dst; the
  // accumulating sum adds dst's own quanta, the residual's sum rescales its quanta to dst's scale.
  dnnl::convolution_forward::primitive_desc conv_pd(int i, size_t k, const dnnl::memory::desc& src,
                                                    const dnnl::memory::desc& dst, bool accumulate, bool act,
                                                    bool residual) const {
    const GraphOp& op = graph_.op(i);
    const ConvLayer& l = layers_[static_cast<size_t>(i)];
    const ConvPart& part = l.parts[k];
    dnnl::post_ops ops;
    if (accumulate) ops.append_sum(1.0f);
    if (act && l.fused_act) ops.append_eltwise(1.0f, dnnl::algorithm::eltwise_relu, l.alpha, 0.0f);
    // The residual, as its quanta in dst (copied or overwritten in place), to dst's scale; as real values in f32.
    if (residual)
      ops.append_sum(value_type(i) == dt::f32 ? 1.0f : scale(op.residual) / scale(i));
    dnnl::primitive_attr attr = user_scratchpad(ops);
    const bool quantised = int8() && !float_conv(i);
    if (quantised) {
      std::vector<float> out_scales(static_cast<size_t>(op.channels));
      for (int o = 0; o < op.channels; ++o)
        out_scales[static_cast<size_t>(o)] = scale(part.value) * part.weight_scale[static_cast<size_t>(o)] / scale(i);
      attr.set_output_scales(1 << 1, out_scales);  // per output channel (dim 1 of dst)
    }
    const int kk = op.kernel, d = op.dilation, pad = d * (kk / 2);
    const dnnl::memory::desc weights(dims{op.channels, part.in, kk, kk}, int8() && !quantised ? dt::f32 : act_type(),
                                     tag::any);
    const dnnl::memory::desc bias(dims{op.channels}, dt::f32, tag::a);
    const dnnl::convolution_forward::desc desc(dnnl::prop_kind::forward_inference, dnnl::algorithm::convolution_direct,
                                               src, weights, bias, dst, {1, 1}, {d - 1, d - 1}, {pad, pad}, {pad, pad});
    return {desc, attr, engine_};
  }

  // A reorder, times `scale` (int8: quantising the input, dequantising a residual into the f32 output).
  void add_reorder(Plan& p, const dnnl::memory::desc& from, const dnnl::memory::desc& to, Binding src, Binding dst,
                   float scale = 1.0f) const {
    dnnl::primitive_attr attr = user_scratchpad();
    if (scale != 1.0f) attr.set_output_scales(0, {scale});
    const dnnl::reorder::primitive_desc pd(engine_, from, engine_, to, attr);
    p.scratchpad = std::max(p.scratchpad, pd.scratchpad_desc().get_size());
    p.steps.push_back({dnnl::reorder(pd), {src, dst}, {}, pd.scratchpad_desc()});
    label(p.steps.back(), "reorder");
  }

  void add_binary(Plan& p, int a, int b, int dst, const dnnl::memory::desc& dst_desc) const {
    const dnnl::binary::desc d(dnnl::algorithm::binary_add, p.values[static_cast<size_t>(a)],
                               p.values[static_cast<size_t>(b)], dst_desc);
    const dnnl::binary::primitive_desc pd(d, user_scratchpad(), engine_);
    p.values[static_cast<size_t>(dst)] = pd.dst_desc();
    p.scratchpad = std::max(p.scratchpad, pd.scratchpad_desc().get_size());
    p.steps.push_back({dnnl::binary(pd), {{DNNL_ARG_SRC_0, a}, {DNNL_ARG_SRC_1, b}, {DNNL_ARG_DST, dst}}, {},
                       pd.scratchpad_desc()});
    label(p.steps.back(), "add");
  }

  // Part `k` of conv `op`'s weights in `desc`'s layout, reordered on first use.
  dnnl::memory packed_weights(int op, size_t k, const dnnl::memory::desc& desc) {
    ConvPart& part = layers_[static_cast<size_t>(op)].parts[k];
    for (const auto& [d, m] : part.packed)
      if (d == desc) return m;
    const GraphOp& o = graph_.op(op);
    const dnnl::memory::desc user(dims{o.channels, part.in, o.kernel, o.kernel}, dt::f32, tag::oihw);
    dnnl::memory src(user, engine_, part.weight.data());
    dnnl::memory dst(desc, engine_);
    dnnl::primitive_attr attr;
    if (desc.data_type() == dt::s8) {  // quantised per output channel (dim 0)
      std::vector<float> inverse(part.weight_scale.size());
      for (size_t c = 0; c < inverse.size(); ++c) inverse[c] = 1.0f / part.weight_scale[c];
      attr.set_output_scales(1 << 0, inverse);
    }
    dnnl::reorder(dnnl::reorder::primitive_desc(engine_, user, engine_, desc, attr)).execute(stream_, src, dst);
    stream_.wait();
    part.packed.emplace_back(desc, dst);
    return dst;
  }

  static void label(Step& s, const std::string& name) {
    s.label = name;
    const char* impl = nullptr;
    if (dnnl_primitive_desc_query(s.primitive.get_primitive_desc(), dnnl_query_impl_info_str, 0, &impl) == dnnl_success && impl)
      s.impl = impl;
  }

  const Graph& graph_;
  std::vector<ConvLayer>& layers_;
  Precision precision_;
  const dnnl::engine& engine_;
  dnnl::stream& stream_;
  std::vector<float> scales_;  // int8_scales (int8 only)
};

// The input skip: a conv reading only the input whose value only the output reads, as its residual.
bool is_input_skip(const Graph& g, int i) {
  const GraphOp& op = g.op(i);
  if (op.kind != OpKind::Conv || i == g.output()) return false;
  for (int v : op.inputs)
    if (g.op(v).kind != OpKind::Input) return false;
  for (int j = 0; j < g.size(); ++j) {
    const GraphOp& r = g.op(j);
    const bool reads = std::find(r.inputs.begin(), r.inputs.end(), i) != r.inputs.end() || r.residual == i;
    if (reads && (j != g.output() || r.residual != i ||
                  std::find(r.inputs.begin(), r.inputs.end(), i) != r.inputs.end()))
      return false;
  }
  return true;
}

}  // namespace

std::vector<float> int8_scales(const Graph& g) {
  const int n = g.size();
  const auto u = [](int i) { return static_cast<size_t>(i); };
  if (g.op(g.output()).kind != OpKind::Conv)
    throw Error(ErrorKind::Usage, "int8 inference needs a graph whose output is a conv");
  bool calibrated = false;
  for (const GraphOp& op : g.ops()) calibrated = calibrated || op.range > 0;
  if (!calibrated)
    throw Error(ErrorKind::Usage, "this model has no int8 calibration (the range of each of its values, which "
                                  "residue-cli calibrate measures); use fp32 or bf16");
  // Kept in f32: the output, the input skip, and the convs the output conv reads, so that the last layer sees
  // the network's final features unquantised (8 bits there cost a visible error in every pixel).
  std::vector<bool> kept_f32(u(n), false);
  kept_f32[u(g.output())] = true;
  for (int v : g.op(g.output()).inputs)
    if (g.op(v).kind == OpKind::Conv) kept_f32[u(v)] = true;
  for (int i = 0; i < n; ++i) kept_f32[u(i)] = kept_f32[u(i)] || is_input_skip(g, i);

  // Values oneDNN moves without rescaling share one scale, the largest range among them: a pool's or an
  // upsample's source and result, an add's. (A residual is rescaled by its conv's sum.)
  std::vector<int> parent(u(n));
  std::iota(parent.begin(), parent.end(), 0);
  const std::function<int(int)> root = [&](int i) { return parent[u(i)] == i ? i : parent[u(i)] = root(parent[u(i)]); };
  const auto unite = [&](int a, int b) { parent[u(root(a))] = root(b); };
  for (int i = 0; i < n; ++i) {
    const GraphOp& op = g.op(i);
    if (kept_f32[u(i)]) continue;
    if (op.kind == OpKind::Pool || op.kind == OpKind::Upsample) unite(i, op.inputs[0]);
    if (op.kind == OpKind::Add) {
      unite(i, op.inputs[0]);
      unite(i, op.inputs[1]);
    }
  }
  std::vector<float> range(u(n), 0.0f);
  for (int i = 0; i < n; ++i)
    if (!kept_f32[u(i)]) range[u(root(i))] = std::max(range[u(root(i))], g.op(i).range);
  std::vector<float> scales(u(n), 0.0f);
  for (int i = 0; i < n; ++i) {
    if (kept_f32[u(i)]) continue;
    const float r = range[u(root(i))];
    scales[u(i)] = r > 0 && std::isfinite(r) ? r / 127.0f : 1.0f;  // a value that was always 0: any scale
  }
  return scales;
}

ConvLayer make_layer(const Graph& graph, const GraphOp& op, const dnnl::engine& engine) {
  ConvLayer l;
  int first = 0;
  const int k = op.kernel;
  for (int v : op.inputs) {
    ConvPart p;
    p.value = v;
    p.in = graph.op(v).channels;
    p.weight.resize(static_cast<size_t>(op.channels) * static_cast<size_t>(p.in * k * k));
    for (int o = 0; o < op.channels; ++o)
      for (int i = 0; i < p.in; ++i)
        for (int t = 0; t < k * k; ++t)
          p.weight[(static_cast<size_t>(o) * static_cast<size_t>(p.in) + static_cast<size_t>(i)) * static_cast<size_t>(k * k) +
                   static_cast<size_t>(t)] = op.w(o, first + i, t / k, t % k);
    first += p.in;
    const size_t per_channel = static_cast<size_t>(p.in * k * k);
    p.weight_scale.assign(static_cast<size_t>(op.channels), 1.0f);
    for (size_t o = 0; o < p.weight_scale.size(); ++o) {
      float m = 0.0f;
      for (size_t t = 0; t < per_channel; ++t) m = std::max(m, std::abs(p.weight[o * per_channel + t]));
      if (m > 0) p.weight_scale[o] = m / 127.0f;
    }
    l.parts.push_back(std::move(p));
  }
  l.bias = dnnl::memory({{op.channels}, dt::f32, tag::a}, engine);
  std::memcpy(l.bias.get_data_handle(), op.bias.data(), op.bias.size() * sizeof(float));
  l.zeros = dnnl::memory({{op.channels}, dt::f32, tag::a}, engine);
  std::memset(l.zeros.get_data_handle(), 0, op.bias.size() * sizeof(float));
  if (op.activation == Activation::ReLU) {
    l.fused_act = true;
    l.alpha = 0.0f;
  } else if (op.activation == Activation::PReLU) {
    const bool uniform = std::all_of(op.slopes.begin(), op.slopes.end(), [&](float a) { return a == op.slopes.front(); });
    if (uniform) {
      l.fused_act = true;
      l.alpha = op.slopes.front();
    } else {
      l.separate_prelu = true;
      l.slopes = dnnl::memory({nchw(op.channels, 1, 1), dt::f32, tag::nchw}, engine);
      std::memcpy(l.slopes.get_data_handle(), op.slopes.data(), op.slopes.size() * sizeof(float));
    }
  }
  return l;
}

Plan make_plan(const Graph& graph, std::vector<ConvLayer>& layers, Precision precision, const dnnl::engine& engine,
               dnnl::stream& stream, int64_t h, int64_t w) {
  return Planner(graph, layers, precision, engine, stream).plan(h, w);
}

}  // namespace residue::nn::onednn
