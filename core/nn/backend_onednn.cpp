// The oneDNN backend: runs a Graph (graph.h) with one oneDNN primitive per op: convolutions (brgemm/JIT
// kernels for the CPU's ISA), max pooling, nearest resampling and binary add, fp32 or bf16 (bf16 weights and
// activations, fp32 accumulation and bias, fp32 output).
//
// Layout: each conv's output takes the layout oneDNN picks for it (format_tag::any: nChw16c or nhwc on
// AVX-512) and its readers take that layout as is, so no reorder runs between layers; only the input (f32
// nhwc -> the first conv's source layout / bf16) and the output are reordered, and only when they differ.
// Fused into the convs: the bias, ReLU and uniform PReLU (eltwise post-op), the residual add (a `sum` post-op
// after the activation: the conv accumulates into the value it overwrites in place, e.g. the ResNet's block
// state; a residual still needed later is copied into the output first). A concat conv runs one primitive per
// input, the later ones accumulating (sum post-op) into the first one's output, the activation on the last.
// PReLU with per-channel slopes: oneDNN 2.6 has a prelu post-op, but no optimised convolution accepts it (it
// falls back to the reference kernel), so it runs as a separate in-place prelu primitive (JIT, one memory
// pass) after its conv; on the paper network at 256 x 256 that costs no measurable time against the fused form.
//
// Primitives depend on the tile size and on the thread count (oneDNN splits the work when a primitive is
// created), so one plan is made per (height, width, threads): every value placed in one arena (arena.h).
// Weights are reordered once into each layout a plan asks for (normally one). The arena and the scratchpad
// are owned by the backend, shared by every plan and grown to the largest tile seen.
//
// Threads: oneDNN runs on OpenMP here. run() gives OpenMP the caller's oneTBB limit
// (tbb::this_task_arena::max_concurrency()). OpenMP's wait policy is set at load time; residue-cli makes it
// passive (core/util/openmp_env.h) so idle threads sleep instead of spinning against other processes.
#include <dlfcn.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <tuple>
#include <unordered_map>

#include <dnnl.hpp>
#include <tbb/task_arena.h>

#include "core/nn/arena.h"
#include "core/nn/backend.h"
#include "core/util/arena_buffer.h"
#include "core/util/error.h"

namespace residue::nn {
namespace {

using dt = dnnl::memory::data_type;
using tag = dnnl::memory::format_tag;
using dims = dnnl::memory::dims;

// libdnnl links libgomp, but our targets do not link it themselves (and the linker refuses symbols of
// indirect dependencies), so omp_set_num_threads is looked up in the already-loaded runtime.
void set_openmp_threads(int n) {
  using SetThreads = void (*)(int);
  static const SetThreads fn = [] {
    SetThreads f = nullptr;
    void* sym = dlsym(RTLD_DEFAULT, "omp_set_num_threads");
    static_assert(sizeof(sym) == sizeof(f));
    std::memcpy(&f, &sym, sizeof(f));
    return f;
  }();
  if (fn) fn(n);
}

const char* isa_name(dnnl::cpu_isa isa) {
  switch (isa) {
    case dnnl::cpu_isa::sse41: return "sse41";
    case dnnl::cpu_isa::avx: return "avx";
    case dnnl::cpu_isa::avx2: return "avx2";
    case dnnl::cpu_isa::avx2_vnni: return "avx2_vnni";
    case dnnl::cpu_isa::avx512_mic: return "avx512_mic";
    case dnnl::cpu_isa::avx512_mic_4ops: return "avx512_mic_4ops";
    case dnnl::cpu_isa::avx512_core: return "avx512_core";
    case dnnl::cpu_isa::avx512_core_vnni: return "avx512_core_vnni";
    case dnnl::cpu_isa::avx512_core_bf16: return "avx512_core_bf16";
    case dnnl::cpu_isa::avx512_core_amx: return "avx512_core_amx";
    default: return "unknown";
  }
}

// Native bf16 arithmetic: AVX512_BF16 (vdpbf16ps) or AMX. oneDNN's ISA values are nested bit sets.
bool has_native_bf16(dnnl::cpu_isa isa) {
  const auto bits = static_cast<unsigned>(isa), bf16 = static_cast<unsigned>(dnnl::cpu_isa::avx512_core_bf16);
  return (bits & bf16) == bf16;
}

// One input of a conv: its slice of the weights (OIHW), reordered on first use into each layout asked for.
struct ConvPart {
  int value = 0;
  int in = 0;
  std::vector<float> weight;
  std::vector<std::pair<dnnl::memory::desc, dnnl::memory>> packed;
};

struct ConvLayer {
  std::vector<ConvPart> parts;
  dnnl::memory bias;    // f32 {out}
  dnnl::memory zeros;   // f32 {out}: the later parts' bias
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

dnnl::memory::dims nchw(int64_t c, int64_t h, int64_t w) { return {1, c, h, w}; }

class OneDnnBackend final : public Backend {
 public:
  OneDnnBackend(const Graph& g, Precision precision)
      : graph_(g), precision_(precision), engine_(dnnl::engine::kind::cpu, 0), stream_(engine_) {
    const dnnl::cpu_isa isa = dnnl::get_effective_cpu_isa();
    if (precision_ == Precision::BF16 && !has_native_bf16(isa))
      throw Error(ErrorKind::Usage, std::string("bf16 inference needs a CPU with AVX512_BF16 or AMX; oneDNN finds ") +
                                        isa_name(isa) + " here. Use fp32.");
    layers_.resize(static_cast<size_t>(g.size()));
    for (int i = 0; i < g.size(); ++i)
      if (g.op(i).kind == OpKind::Conv) layers_[static_cast<size_t>(i)] = make_layer(g.op(i));

    // What runs, from a 256 x 256 tile (rounded to the alignment).
    set_openmp_threads(tbb::this_task_arena::max_concurrency());
    const int64_t a = g.alignment(), side = (256 + a - 1) / a * a;
    const std::string impl = plan_for(side, side, tbb::this_task_arena::max_concurrency()).impl;
    if (precision_ == Precision::BF16 && impl.rfind("ref", 0) == 0)
      throw Error(ErrorKind::Usage, "oneDNN offers no optimised bf16 convolution on this CPU (" +
                                        std::string(isa_name(isa)) + "); use fp32");
    description_ = std::string("onednn ") + to_string(precision_) + " (" + impl + ")";
  }

  std::string description() const override { return description_; }

  size_t scratch_bytes(int64_t width, int64_t height) const override {
    const int threads = tbb::this_task_arena::max_concurrency();
    set_openmp_threads(threads);
    const Plan& p = const_cast<OneDnnBackend*>(this)->plan_for(height, width, threads);
    return aligned(p.arena.bytes) + aligned(p.scratchpad);
  }

  // Computes the whole tile whatever is `needed`: a conv over part of a value would need a primitive per region.
  void execute(const Image& input, Image& output, const CancelToken* cancel, const std::optional<Rect>&) override {
    graph_.check_tile(input);
    const int64_t h = input.height(), w = input.width();
    output = Image(w, h, graph_.output_channels());
    if (h == 0 || w == 0) return;
    const int threads = tbb::this_task_arena::max_concurrency();
    set_openmp_threads(threads);
    const Plan& plan = plan_for(h, w, threads);
    arena_.grow(plan.arena.bytes);
    scratchpad_.grow(plan.scratchpad);

    auto* base = static_cast<char*>(arena_.data());
    std::vector<dnnl::memory> mem(static_cast<size_t>(graph_.size()));
    for (int i = 0; i < graph_.size(); ++i) {
      const auto u = static_cast<size_t>(i);
      void* ptr = base + plan.arena.offset[u];
      if (graph_.op(i).kind == OpKind::Input && plan.input_direct) ptr = const_cast<float*>(input.data());  // read only
      if (i == graph_.output() && plan.output_direct) ptr = output.data();
      mem[u] = dnnl::memory(plan.values[u], engine_, ptr);
    }
    const dnnl::memory user_in(plan.user_in, engine_, const_cast<float*>(input.data()));
    const dnnl::memory user_out(plan.user_out, engine_, output.data());
    for (const Step& s : plan.steps) {
      throw_if_cancelled(cancel);  // between primitives: oneDNN cannot stop one part-way
      std::unordered_map<int, dnnl::memory> args = s.fixed;
      for (const Binding& b : s.bindings)
        args[b.arg] = b.user_input ? user_in : b.user_output ? user_out : mem[static_cast<size_t>(b.value)];
      if (s.scratchpad.get_size() > 0) args[DNNL_ARG_SCRATCHPAD] = dnnl::memory(s.scratchpad, engine_, scratchpad_.data());
      const auto t0 = std::chrono::steady_clock::now();
      s.primitive.execute(stream_, args);
      if (profile_) {  // RESIDUE_PROFILE=1: each primitive's time (waits for it, so only for measuring)
        stream_.wait();
        std::fprintf(stderr, "profile %lldx%lld %-12s %-34s %8.2f ms\n", static_cast<long long>(w),
                     static_cast<long long>(h), s.label.c_str(), s.impl.c_str(),
                     std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      }
    }
    stream_.wait();
  }

 private:
  dt act_type() const { return precision_ == Precision::BF16 ? dt::bf16 : dt::f32; }

  ConvLayer make_layer(const GraphOp& op) {
    ConvLayer l;
    int first = 0;
    const int k = op.kernel;
    for (int v : op.inputs) {
      ConvPart p;
      p.value = v;
      p.in = graph_.op(v).channels;
      p.weight.resize(static_cast<size_t>(op.channels) * static_cast<size_t>(p.in * k * k));
      for (int o = 0; o < op.channels; ++o)
        for (int i = 0; i < p.in; ++i)
          for (int t = 0; t < k * k; ++t)
            p.weight[(static_cast<size_t>(o) * static_cast<size_t>(p.in) + static_cast<size_t>(i)) * static_cast<size_t>(k * k) +
                     static_cast<size_t>(t)] = op.w(o, first + i, t / k, t % k);
      first += p.in;
      l.parts.push_back(std::move(p));
    }
    l.bias = dnnl::memory({{op.channels}, dt::f32, tag::a}, engine_);
    std::memcpy(l.bias.get_data_handle(), op.bias.data(), op.bias.size() * sizeof(float));
    l.zeros = dnnl::memory({{op.channels}, dt::f32, tag::a}, engine_);
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
        l.slopes = dnnl::memory({nchw(op.channels, 1, 1), dt::f32, tag::nchw}, engine_);
        std::memcpy(l.slopes.get_data_handle(), op.slopes.data(), op.slopes.size() * sizeof(float));
      }
    }
    return l;
  }

  static dnnl::primitive_attr user_scratchpad(dnnl::post_ops ops = {}) {
    dnnl::primitive_attr attr;
    attr.set_post_ops(ops);
    attr.set_scratchpad_mode(dnnl::scratchpad_mode::user);
    return attr;
  }

  // One part's conv: `accumulate` adds what dst holds (sum post-op) before the activation; `residual` adds it
  // after; `act` applies the fused activation; `bias`: this part adds the bias.
  dnnl::convolution_forward::primitive_desc conv_pd(const GraphOp& op, const ConvPart& part, const ConvLayer& l,
                                                    const dnnl::memory::desc& src, const dnnl::memory::desc& dst,
                                                    bool accumulate, bool act, bool residual) const {
    dnnl::post_ops ops;
    if (accumulate) ops.append_sum(1.0f);
    if (act && l.fused_act) ops.append_eltwise(1.0f, dnnl::algorithm::eltwise_relu, l.alpha, 0.0f);
    if (residual) ops.append_sum(1.0f);
    const int k = op.kernel, d = op.dilation, pad = d * (k / 2);
    const dnnl::memory::desc weights(dims{op.channels, part.in, k, k}, act_type(), tag::any);
    const dnnl::memory::desc bias(dims{op.channels}, dt::f32, tag::a);
    const dnnl::convolution_forward::desc desc(dnnl::prop_kind::forward_inference, dnnl::algorithm::convolution_direct,
                                               src, weights, bias, dst, {1, 1}, {d - 1, d - 1}, {pad, pad}, {pad, pad});
    return {desc, user_scratchpad(ops), engine_};
  }

  const Plan& plan_for(int64_t h, int64_t w, int threads) {
    const auto key = std::make_tuple(h, w, threads);
    if (auto it = plans_.find(key); it != plans_.end()) return it->second;
    if (plans_.size() >= 16) plans_.clear();  // tile sizes are few; this only bounds a pathological caller

    Plan p;
    const int n = graph_.size();
    p.values.resize(static_cast<size_t>(n));
    p.user_in = dnnl::memory::desc(nchw(graph_.input_channels(), h, w), dt::f32, tag::nhwc);
    p.user_out = dnnl::memory::desc(nchw(graph_.output_channels(), h, w), dt::f32, tag::nhwc);
    auto dims_of = [&](int i) {
      const GraphOp& o = graph_.op(i);
      return nchw(o.channels, h >> o.level, w >> o.level);
    };
    auto out_type = [&](int i) { return i == graph_.output() ? dt::f32 : act_type(); };
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
            if (c.kind != OpKind::Conv || c.inputs.front() != i) continue;
            const ConvLayer& l = layers_[static_cast<size_t>(j)];
            chosen = conv_pd(c, l.parts.front(), l, dnnl::memory::desc(dims_of(i), act_type(), tag::any),
                             dnnl::memory::desc(dims_of(j), out_type(j), tag::any), false, true, false)
                         .src_desc();
            break;
          }
          p.values[u] = chosen;
          p.input_direct = chosen == p.user_in;
          if (!p.input_direct) add_reorder(p, p.user_in, chosen, {DNNL_ARG_FROM, -1, true, false}, {DNNL_ARG_TO, i});
          break;
        }
        case OpKind::Conv: {
          const ConvLayer& l = layers_[u];
          const bool residual = op.residual >= 0;
          dnnl::memory::desc dst = residual ? p.values[static_cast<size_t>(op.residual)]
                                            : dnnl::memory::desc(dims_of(i), out_type(i), tag::any);
          if (residual && i == graph_.output() && dst.data_type() != dt::f32)
            dst = dnnl::memory::desc(dims_of(i), dt::f32, tag::any);
          const bool prelu_separate = l.separate_prelu;
          if (prelu_separate && residual)
            throw Error(ErrorKind::Usage, "conv " + op.name + ": per-channel PReLU followed by a residual add is not "
                                          "supported by the onednn backend; use --backend eigen");
          const bool sum_residual = residual && !prelu_separate;
          for (size_t k = 0; k < l.parts.size(); ++k) {
            const ConvPart& part = l.parts[k];
            const bool first = k == 0, last = k + 1 == l.parts.size();
            const auto pd = conv_pd(op, part, l, p.values[static_cast<size_t>(part.value)], dst, !first, last,
                                    last && sum_residual);
            if (first) {
              dst = pd.dst_desc();
              p.values[u] = dst;
              // A residual read again later cannot be overwritten: it is copied into this op's output first
              // (the copy is dropped below where the arena plan lets the conv run in place).
              if (residual) {
                add_reorder(p, p.values[static_cast<size_t>(op.residual)], dst, {DNNL_ARG_FROM, op.residual}, {DNNL_ARG_TO, i});
                p.steps.back().residual_copy_for = i;
              }
            }
            const double cost = static_cast<double>(op.channels) * part.in * op.kernel * op.kernel / (1 << (2 * op.level));
            if (cost > costliest) {
              costliest = cost;
              p.impl = pd.impl_info_str();
            }
            p.scratchpad = std::max(p.scratchpad, pd.scratchpad_desc().get_size());
            p.steps.push_back({dnnl::convolution_forward(pd),
                               {{DNNL_ARG_SRC, part.value}, {DNNL_ARG_DST, i}},
                               {{DNNL_ARG_WEIGHTS, packed_weights(i, k, pd.weights_desc())},
                                {DNNL_ARG_BIAS, first ? l.bias : l.zeros}},
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
                                              dnnl::memory::desc(dims_of(i), act_type(), tag::any), {2, 2}, {2, 2},
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
    return plans_.emplace(key, std::move(p)).first->second;
  }

  void add_reorder(Plan& p, const dnnl::memory::desc& from, const dnnl::memory::desc& to, Binding src, Binding dst) const {
    const dnnl::reorder::primitive_desc pd(engine_, from, engine_, to, user_scratchpad());
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
    dnnl::reorder(src, dst).execute(stream_, src, dst);
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

  static size_t aligned(size_t bytes) { return (bytes + 63) / 64 * 64; }

  Graph graph_;
  bool profile_ = std::getenv("RESIDUE_PROFILE") != nullptr;
  Precision precision_;
  dnnl::engine engine_;
  dnnl::stream stream_;
  std::string description_;
  std::vector<ConvLayer> layers_;
  std::map<std::tuple<int64_t, int64_t, int>, Plan> plans_;
  ArenaBuffer arena_, scratchpad_;
};

}  // namespace

std::unique_ptr<Backend> make_onednn_backend(const Graph& graph, Precision precision) {
  return std::make_unique<OneDnnBackend>(graph, precision);
}

}  // namespace residue::nn
