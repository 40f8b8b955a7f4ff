// The oneDNN backend: runs a Graph (graph.h) with one oneDNN primitive per op: convolutions (brgemm/JIT
// kernels for the CPU's ISA), max pooling, nearest resampling and binary add, fp32, bf16 (bf16 weights and
// activations, fp32 accumulation and bias, fp32 output) or int8 (graph_plan_onednn.h).
//
// Layout, fusion and the plan of each tile size: graph_plan_onednn.h.
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
#include <cmath>
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
#include "core/nn/graph_plan_onednn.h"
#include "core/util/arena_buffer.h"
#include "core/util/error.h"

namespace residue::nn {
namespace {

using onednn::ConvLayer;
using onednn::Plan;
using onednn::Step;
using onednn::Binding;

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
      if (g.op(i).kind == OpKind::Conv) layers_[static_cast<size_t>(i)] = onednn::make_layer(g, g.op(i), engine_);

    // What runs, from a 256 x 256 tile (rounded to the alignment).
    set_openmp_threads(tbb::this_task_arena::max_concurrency());
    const int64_t a = g.alignment(), side = (256 + a - 1) / a * a;
    const std::string impl = plan_for(side, side, tbb::this_task_arena::max_concurrency()).impl;
    if (precision_ != Precision::FP32 && impl.rfind("ref", 0) == 0)
      throw Error(ErrorKind::Usage, std::string("oneDNN offers no optimised ") + to_string(precision_) +
                                        " convolution on this CPU (" + isa_name(isa) + "); use fp32");
    description_ = std::string("onednn ") + to_string(precision_) + " (" + impl + ")";
  }

  std::string description() const override { return description_; }

  void record_ranges(std::vector<float>* ranges, double quantile) override {
    if (ranges && precision_ != Precision::FP32)
      throw Error(ErrorKind::Usage, "value ranges are recorded in fp32, not " + std::string(to_string(precision_)));
    if (!(quantile > 0 && quantile <= 1))
      throw Error(ErrorKind::Usage, "a range's quantile must be in (0, 1], not " + std::to_string(quantile));
    if (ranges) ranges->resize(static_cast<size_t>(graph_.size()), 0.0f);
    ranges_ = ranges;
    quantile_ = quantile;
  }

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
    if (ranges_)
      for (int i = 0; i < graph_.size(); ++i)
        if (graph_.op(i).kind == OpKind::Input) raise_range(i, user_in);
    for (const Step& s : plan.steps) {
      throw_if_cancelled(cancel);  // between primitives: oneDNN cannot stop one part-way
      std::unordered_map<int, dnnl::memory> args = s.fixed;
      for (const Binding& b : s.bindings)
        args[b.arg] = b.user_input ? user_in : b.user_output ? user_out : mem[static_cast<size_t>(b.value)];
      if (s.scratchpad.get_size() > 0) args[DNNL_ARG_SCRATCHPAD] = dnnl::memory(s.scratchpad, engine_, scratchpad_.data());
      const auto t0 = std::chrono::steady_clock::now();
      s.primitive.execute(stream_, args);
      if (ranges_) {  // what the step wrote: a value of the graph (a partial sum too), or the output
        stream_.wait();
        for (const Binding& b : s.bindings)
          if (b.arg == DNNL_ARG_DST || b.arg == DNNL_ARG_TO) {
            const int value = b.user_output ? graph_.output() : b.value;
            if (value >= 0) raise_range(value, b.user_output ? user_out : mem[static_cast<size_t>(value)]);
          }
      }
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
  const Plan& plan_for(int64_t h, int64_t w, int threads) {
    const auto key = std::make_tuple(h, w, threads);
    if (auto it = plans_.find(key); it != plans_.end()) return it->second;
    if (plans_.size() >= 16) plans_.clear();  // tile sizes are few; this only bounds a pathological caller
    return plans_.emplace(key, onednn::make_plan(graph_, layers_, precision_, engine_, stream_, h, w)).first->second;
  }

  static size_t aligned(size_t bytes) { return (bytes + 63) / 64 * 64; }

  // Raises ranges_[value] to the quantile_ of |x| over an f32 memory's finite non-zero values (the padding
  // oneDNN zeroes, and the zeros a ReLU makes, left out), the largest when quantile_ is 1.
  void raise_range(int value, const dnnl::memory& m) {
    const auto* x = static_cast<const float*>(m.get_data_handle());
    const size_t n = m.get_desc().get_size() / sizeof(float);
    float& top = (*ranges_)[static_cast<size_t>(value)];
    if (quantile_ >= 1) {
      for (size_t k = 0; k < n; ++k)
        if (std::isfinite(x[k])) top = std::max(top, std::abs(x[k]));
      return;
    }
    std::vector<float> a;
    a.reserve(n);
    for (size_t k = 0; k < n; ++k)
      if (std::isfinite(x[k]) && x[k] != 0.0f) a.push_back(std::abs(x[k]));
    if (a.empty()) return;
    const auto at = std::min(a.size() - 1, static_cast<size_t>(quantile_ * static_cast<double>(a.size())));
    std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(at), a.end());
    top = std::max(top, a[at]);
  }

  Graph graph_;
  bool profile_ = std::getenv("RESIDUE_PROFILE") != nullptr;
  Precision precision_;
  dnnl::engine engine_;
  dnnl::stream stream_;
  std::string description_;
  std::vector<ConvLayer> layers_;
  std::map<std::tuple<int64_t, int64_t, int>, Plan> plans_;
  std::vector<float>* ranges_ = nullptr;  // record_ranges
  double quantile_ = 1.0;
  ArenaBuffer arena_, scratchpad_;
};

}  // namespace

bool onednn_has_native_bf16() { return has_native_bf16(dnnl::get_effective_cpu_isa()); }

std::unique_ptr<Backend> make_onednn_backend(const Graph& graph, Precision precision) {
  return std::make_unique<OneDnnBackend>(graph, precision);
}

}  // namespace residue::nn
