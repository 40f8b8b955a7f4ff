// The oneDNN backend: every 3x3 conv is one oneDNN convolution primitive (brgemm/JIT kernels for the CPU's
// ISA), fp32 or bf16 (bf16 weights and activations, fp32 accumulation and bias, fp32 output).
//
// Layout: the activation layout is the one oneDNN picks (format_tag::any) for a W -> W conv, chosen once
// and kept through the network (channels-last nhwc on AVX-512), so no reorder runs between layers; only
// the input (f32 nhwc -> the head's source layout / bf16) and the output are reordered, and only when they
// differ. Fused into the convs: the bias, the residual add (a `sum` post-op: the conv accumulates into the
// block state in place) and the network-wide skip (the tail accumulates into the head's output).
// PReLU: oneDNN 2.6 has a prelu post-op, but no optimised convolution accepts it (it falls back to the
// reference kernel), so a per-channel PReLU runs as a separate in-place prelu primitive (JIT, one memory
// pass) after its conv; on the paper network at 256 x 256 that costs no measurable time against the fused
// form, which is used when a layer's slopes are all equal (an eltwise leaky-ReLU post-op).
//
// Primitives depend on the tile size and on the thread count (oneDNN splits the work when a primitive is
// created), so one plan is cached per (height, width, threads); weights are reordered once into each
// layout a plan asks for (normally one). Activation buffers and the scratchpad are owned by the backend,
// shared by every plan and grown to the largest tile seen.
//
// Threads: oneDNN runs on OpenMP here. run() gives OpenMP the caller's oneTBB limit
// (tbb::this_task_arena::max_concurrency()). OpenMP's wait policy is set at load time; residue-cli makes it
// passive (core/util/openmp_env.h) so idle threads sleep instead of spinning against other processes.
#include <dlfcn.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <map>
#include <tuple>
#include <unordered_map>

#include <dnnl.hpp>
#include <tbb/task_arena.h>

#include "core/nn/backend.h"
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

// One conv layer with what oneDNN needs besides the primitive.
struct Layer {
  int in = 0, out = 0;
  std::vector<float> weight;  // OIHW, kept to reorder into another layout should a plan ask for one
  dnnl::memory bias;          // f32 {out}
  dnnl::memory slopes;        // f32 {1, out, 1, 1}; empty: no PReLU or a fused uniform one
  bool prelu = false;         // PReLU after the conv (+ bias)
  bool uniform_prelu = false; // all slopes equal: fused as eltwise_relu(alpha)
  float alpha = 0.0f;
  bool accumulate = false;    // dst += conv(src) + bias (sum post-op)
  int dilation = 1;           // taps this many pixels apart (oneDNN counts the gaps: dilation - 1)
  std::vector<std::pair<dnnl::memory::desc, dnnl::memory>> packed;  // weights per layout
};

// Where a primitive reads or writes: a buffer of the backend, the caller's input or output.
enum class Buffer { Input, Output, In, Out, Head, State, Temp };

struct Step {
  dnnl::primitive primitive;
  std::vector<std::pair<int, Buffer>> buffers;    // DNNL_ARG_* -> buffer, bound at run time
  std::unordered_map<int, dnnl::memory> fixed;    // weights, bias, slopes
  dnnl::memory::desc scratchpad;
};

struct Descs {
  dnnl::memory::desc user_in, user_out, in, act, out;
  std::vector<dnnl::convolution_forward::primitive_desc> convs;
  size_t scratchpad = 0;
};

struct Plan {
  Descs d;
  std::vector<Step> steps;
};

dnnl::memory::dims nchw(int64_t c, int64_t h, int64_t w) { return {1, c, h, w}; }

class OneDnnBackend final : public Backend {
 public:
  OneDnnBackend(const Network& n, Precision precision)
      : arch_(n.arch), precision_(precision), engine_(dnnl::engine::kind::cpu, 0), stream_(engine_) {
    const dnnl::cpu_isa isa = dnnl::get_effective_cpu_isa();
    if (precision_ == Precision::BF16 && !has_native_bf16(isa))
      throw Error(ErrorKind::Usage, std::string("bf16 inference needs a CPU with AVX512_BF16 or AMX; oneDNN finds ") +
                                        isa_name(isa) + " here. Use fp32.");
    add_layer(n.head, n.head_prelu, false, 1);
    for (size_t b = 0; b < n.blocks.size(); ++b) {
      const int d = arch_.dilation(static_cast<int>(b));
      add_layer(n.blocks[b].conv1, n.blocks[b].prelu, false, d);
      add_layer(n.blocks[b].conv2, {}, true, d);
    }
    add_layer(n.tail, {}, true, 1);
    add_layer(n.out, {}, false, 1);

    // What runs, from a representative W -> W layer on a 256 x 256 tile.
    const int threads = tbb::this_task_arena::max_concurrency();
    set_openmp_threads(threads);
    const Descs d = make_descs(256, 256);
    const std::string impl = d.convs.size() > 2 ? d.convs[1].impl_info_str() : d.convs[0].impl_info_str();
    if (precision_ == Precision::BF16 && impl.rfind("ref", 0) == 0)
      throw Error(ErrorKind::Usage, "oneDNN offers no optimised bf16 convolution on this CPU (" +
                                        std::string(isa_name(isa)) + "); use fp32");
    description_ = std::string("onednn ") + to_string(precision_) + " (" + impl + ")";
  }

  std::string description() const override { return description_; }

  size_t scratch_bytes(int64_t width, int64_t height) const override {
    set_openmp_threads(tbb::this_task_arena::max_concurrency());
    return bytes_for(make_descs(height, width));
  }

  void run(const Image& input, Image& output) override {
    if (input.channels() != arch_.in_channels())
      throw Error(ErrorKind::Input, "the network expects " + std::to_string(arch_.in_channels()) +
                                        " input channels, the tile has " + std::to_string(input.channels()));
    const int64_t h = input.height(), w = input.width();
    output = Image(w, h, 3);
    if (h == 0 || w == 0) return;
    const int threads = tbb::this_task_arena::max_concurrency();
    set_openmp_threads(threads);
    const Plan& plan = plan_for(h, w, threads);
    reserve(plan.d);

    auto mem = [&](Buffer b) -> dnnl::memory {
      const Descs& d = plan.d;
      switch (b) {
        case Buffer::Input: return {d.user_in, engine_, const_cast<float*>(input.data())};  // read only
        case Buffer::Output: return {d.user_out, engine_, output.data()};
        case Buffer::In: return {d.in, engine_, in_.get()};
        case Buffer::Out: return {d.out, engine_, out_.get()};
        case Buffer::Head: return {d.act, engine_, head_.get()};
        case Buffer::State: return {d.act, engine_, state_.get()};
        case Buffer::Temp: return {d.act, engine_, temp_.get()};
      }
      return {};
    };
    for (const Step& s : plan.steps) {
      std::unordered_map<int, dnnl::memory> args = s.fixed;
      for (const auto& [arg, buffer] : s.buffers) args[arg] = mem(buffer);
      if (s.scratchpad.get_size() > 0)
        args[DNNL_ARG_SCRATCHPAD] = dnnl::memory(s.scratchpad, engine_, scratchpad_.get());
      s.primitive.execute(stream_, args);
    }
    stream_.wait();
    if (arch_.input_skip) add_input_skip(input, output);
  }

 private:
  struct FreeDeleter {
    void operator()(void* p) const { std::free(p); }
  };
  using Bytes = std::unique_ptr<void, FreeDeleter>;

  dt act_type() const { return precision_ == Precision::BF16 ? dt::bf16 : dt::f32; }

  void add_layer(const Conv3x3& c, const std::vector<float>& prelu, bool accumulate, int dilation) {
    Layer l;
    l.dilation = dilation;
    l.in = c.in;
    l.out = c.out;
    l.weight = c.weight;
    l.accumulate = accumulate;
    l.bias = dnnl::memory({{c.out}, dt::f32, tag::a}, engine_);
    std::vector<float> bias = c.bias;
    bias.resize(static_cast<size_t>(c.out), 0.0f);
    std::memcpy(l.bias.get_data_handle(), bias.data(), bias.size() * sizeof(float));
    if (!prelu.empty()) {
      l.prelu = true;
      l.uniform_prelu = std::all_of(prelu.begin(), prelu.end(), [&](float a) { return a == prelu.front(); });
      l.alpha = prelu.front();
      if (!l.uniform_prelu) {
        l.slopes = dnnl::memory({nchw(c.out, 1, 1), dt::f32, tag::nchw}, engine_);
        std::memcpy(l.slopes.get_data_handle(), prelu.data(), prelu.size() * sizeof(float));
      }
    }
    layers_.push_back(std::move(l));
  }

  dnnl::primitive_attr conv_attr(const Layer& l) const {
    dnnl::post_ops ops;
    if (l.accumulate) ops.append_sum(1.0f);
    if (l.prelu && l.uniform_prelu) ops.append_eltwise(1.0f, dnnl::algorithm::eltwise_relu, l.alpha, 0.0f);
    dnnl::primitive_attr attr;
    attr.set_post_ops(ops);
    attr.set_scratchpad_mode(dnnl::scratchpad_mode::user);
    return attr;
  }

  dnnl::convolution_forward::primitive_desc conv_pd(const Layer& l, const dnnl::memory::desc& src,
                                                    const dnnl::memory::desc& dst) const {
    const dnnl::memory::desc weights(dims{l.out, l.in, 3, 3}, act_type(), tag::any);
    const dnnl::memory::desc bias(dims{l.out}, dt::f32, tag::a);
    const dnnl::convolution_forward::desc d(dnnl::prop_kind::forward_inference, dnnl::algorithm::convolution_direct,
                                            src, weights, bias, dst, {1, 1}, {l.dilation - 1, l.dilation - 1},
                                            {l.dilation, l.dilation}, {l.dilation, l.dilation});
    return {d, conv_attr(l), engine_};
  }

  // The primitive descriptors for a tile, given the thread count already set for OpenMP.
  Descs make_descs(int64_t h, int64_t w) const {
    Descs d;
    const dt t = act_type();
    const int width = arch_.width;
    d.user_in = dnnl::memory::desc(nchw(arch_.in_channels(), h, w), dt::f32, tag::nhwc);
    d.user_out = dnnl::memory::desc(nchw(3, h, w), dt::f32, tag::nhwc);
    // The activation layout: oneDNN's choice for a W -> W conv with the residual sum, the common case.
    {
      const dnnl::memory::desc any(nchw(width, h, w), t, tag::any);
      Layer probe;
      probe.in = probe.out = width;
      probe.accumulate = true;
      d.act = conv_pd(probe, any, any).dst_desc();
    }
    const size_t n = layers_.size();
    for (size_t i = 0; i < n; ++i) {
      const Layer& l = layers_[i];
      const dnnl::memory::desc src = i == 0 ? dnnl::memory::desc(nchw(l.in, h, w), t, tag::any) : d.act;
      const dnnl::memory::desc dst = i + 1 == n ? dnnl::memory::desc(nchw(l.out, h, w), dt::f32, tag::any) : d.act;
      d.convs.push_back(conv_pd(l, src, dst));
      d.scratchpad = std::max(d.scratchpad, d.convs.back().scratchpad_desc().get_size());
    }
    d.in = d.convs.front().src_desc();
    d.out = d.convs.back().dst_desc();
    return d;
  }

  static size_t aligned(size_t bytes) { return (bytes + 63) / 64 * 64; }

  // The buffers run() holds for a tile (the convs' scratchpad; reorders and prelu need none on x64).
  size_t bytes_for(const Descs& d) const {
    size_t total = 3 * aligned(d.act.get_size()) + aligned(d.scratchpad);
    if (d.in != d.user_in) total += aligned(d.in.get_size());
    if (d.out != d.user_out) total += aligned(d.out.get_size());
    return total;
  }

  const Plan& plan_for(int64_t h, int64_t w, int threads) {
    const auto key = std::make_tuple(h, w, threads);
    if (auto it = plans_.find(key); it != plans_.end()) return it->second;
    if (plans_.size() >= 16) plans_.clear();  // tile sizes are few; this only bounds a pathological caller

    Plan p;
    p.d = make_descs(h, w);
    auto reorder = [&](const dnnl::memory::desc& from, const dnnl::memory::desc& to, Buffer src, Buffer dst) {
      dnnl::primitive_attr attr;
      attr.set_scratchpad_mode(dnnl::scratchpad_mode::user);
      const dnnl::reorder::primitive_desc pd(engine_, from, engine_, to, attr);
      p.d.scratchpad = std::max(p.d.scratchpad, pd.scratchpad_desc().get_size());
      p.steps.push_back({dnnl::reorder(pd), {{DNNL_ARG_FROM, src}, {DNNL_ARG_TO, dst}}, {}, pd.scratchpad_desc()});
    };
    auto conv = [&](size_t i, Buffer src, Buffer dst) {
      const Layer& l = layers_[i];
      const auto& pd = p.d.convs[i];
      p.steps.push_back({dnnl::convolution_forward(pd),
                         {{DNNL_ARG_SRC, src}, {DNNL_ARG_DST, dst}},
                         {{DNNL_ARG_WEIGHTS, packed_weights(i, pd.weights_desc())}, {DNNL_ARG_BIAS, l.bias}},
                         pd.scratchpad_desc()});
      if (l.prelu && !l.uniform_prelu) {
        const dnnl::prelu_forward::desc pdesc(dnnl::prop_kind::forward_inference, p.d.act, l.slopes.get_desc());
        dnnl::primitive_attr attr;
        attr.set_scratchpad_mode(dnnl::scratchpad_mode::user);
        const dnnl::prelu_forward::primitive_desc prelu_pd(pdesc, attr, engine_);
        p.d.scratchpad = std::max(p.d.scratchpad, prelu_pd.scratchpad_desc().get_size());
        p.steps.push_back({dnnl::prelu_forward(prelu_pd), {{DNNL_ARG_SRC, dst}, {DNNL_ARG_DST, dst}},  // in place
                           {{DNNL_ARG_WEIGHTS, l.slopes}}, prelu_pd.scratchpad_desc()});
      }
    };

    const bool direct_in = p.d.in == p.d.user_in, direct_out = p.d.out == p.d.user_out;
    if (!direct_in) reorder(p.d.user_in, p.d.in, Buffer::Input, Buffer::In);
    conv(0, direct_in ? Buffer::Input : Buffer::In, Buffer::Head);
    reorder(p.d.act, p.d.act, Buffer::Head, Buffer::State);  // the block state starts as the head's output
    const size_t n = layers_.size();
    for (size_t i = 1; i + 2 < n; i += 2) {
      conv(i, Buffer::State, Buffer::Temp);
      conv(i + 1, Buffer::Temp, Buffer::State);  // State += conv2(Temp) + bias
    }
    conv(n - 2, Buffer::State, Buffer::Head);  // Head += tail(State) + bias
    conv(n - 1, Buffer::Head, direct_out ? Buffer::Output : Buffer::Out);
    if (!direct_out) reorder(p.d.out, p.d.user_out, Buffer::Out, Buffer::Output);
    return plans_.emplace(key, std::move(p)).first->second;
  }

  // The layer's weights in `desc`'s layout, reordered on first use.
  dnnl::memory packed_weights(size_t i, const dnnl::memory::desc& desc) {
    Layer& l = layers_[i];
    for (const auto& [d, m] : l.packed)
      if (d == desc) return m;
    const dnnl::memory::desc user(dims{l.out, l.in, 3, 3}, dt::f32, tag::oihw);
    dnnl::memory src(user, engine_, l.weight.data());
    dnnl::memory dst(desc, engine_);
    dnnl::reorder(src, dst).execute(stream_, src, dst);
    stream_.wait();
    l.packed.emplace_back(desc, dst);
    return dst;
  }

  static void grow(Bytes& buffer, size_t& capacity, size_t bytes) {
    if (bytes <= capacity) return;
    buffer.reset();
    capacity = 0;
    void* p = std::aligned_alloc(64, aligned(bytes));
    if (!p) throw std::bad_alloc();
    buffer.reset(p);
    capacity = bytes;
  }

  void reserve(const Descs& d) {
    grow(head_, head_size_, d.act.get_size());
    grow(state_, state_size_, d.act.get_size());
    grow(temp_, temp_size_, d.act.get_size());
    if (d.in != d.user_in) grow(in_, in_size_, d.in.get_size());
    if (d.out != d.user_out) grow(out_, out_size_, d.out.get_size());
    grow(scratchpad_, scratchpad_size_, std::max<size_t>(d.scratchpad, 64));
  }

  Architecture arch_;
  Precision precision_;
  dnnl::engine engine_;
  dnnl::stream stream_;
  std::string description_;
  std::vector<Layer> layers_;
  std::map<std::tuple<int64_t, int64_t, int>, Plan> plans_;
  Bytes head_, state_, temp_, in_, out_, scratchpad_;
  size_t head_size_ = 0, state_size_ = 0, temp_size_ = 0, in_size_ = 0, out_size_ = 0, scratchpad_size_ = 0;
};

}  // namespace

std::unique_ptr<Backend> make_onednn_backend(const Network& network, Precision precision) {
  return std::make_unique<OneDnnBackend>(network, precision);
}

}  // namespace residue::nn
