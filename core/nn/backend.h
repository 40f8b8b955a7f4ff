// Backends run a network graph (graph.h) on one tile. One interface, chosen at run time:
//   "eigen"   portable fp32 (always built; the reference): an AVX-512 direct conv kernel where the CPU has it,
//             else im2col + Eigen GEMM; rows in parallel on oneTBB
//   "onednn"  oneDNN fp32 / bf16 (AVX-512, AMX where present) / int8 (VNNI where present; a calibrated model:
//             graph.h's ranges), when built with oneDNN
// Both plan each tile size once: every op's output placed in one arena (arena.h), reused tile after tile.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/image/image.h"
#include "core/nn/graph.h"
#include "core/nn/network.h"
#include "core/util/cancel.h"

namespace residue::nn {

// INT8: 8-bit weights (a scale per output channel) and activations (a scale per value, from the model's
// calibration), 32-bit accumulation; the input's transform and the network's output in float.
enum class Precision { FP32, BF16, INT8 };
const char* to_string(Precision p);
// Every precision's name, in order ("fp32", "bf16", "int8"): what --precision and the viewer offer.
std::vector<std::string> precision_names();
// The precision a name stands for; Error(Usage) naming the valid ones otherwise.
Precision parse_precision(std::string_view name);

struct BackendOptions {
  Precision precision = Precision::FP32;
};

class Backend {
 public:
  virtual ~Backend() = default;
  // What runs, e.g. "eigen fp32" or "onednn bf16 (avx512_core_amx)".
  virtual std::string description() const = 0;
  // The network on one tile: `input` is H x W x C_in (the model's feature planes, NHWC; H and W multiples of the
  // graph's alignment), `output` gets H x W x C_out (the network's raw output). Convolutions pad with zeros at
  // the tile's borders.
  // Threads: whatever oneTBB's current arena allows (the caller limits it).
  // `cancel`, when raised, stops the run between layers (and between rows of a layer where the backend can),
  // throwing Cancelled.
  // `needed`: the part of the output the caller reads (the tile without its halo); a backend may then leave the
  // rest of `output` unspecified (eigen computes each layer only where `needed` depends on it and leaves zeros).
  void run(const Image& input, Image& output, const CancelToken* cancel = nullptr,
           const std::optional<Rect>& needed = std::nullopt) {
    execute(input, output, cancel, needed);
  }
  // Scratch memory run() allocates for a tile of this size, in bytes (for memory-bounded tiling).
  virtual size_t scratch_bytes(int64_t width, int64_t height) const = 0;
  // Calibration for int8 (graph.h, GraphOp::range): from now on every run raises (*ranges)[op] to the largest
  // |value| op's output took, partial sums included (a concat conv's first inputs), or with `quantile` < 1 to
  // that quantile of each run's non-zero |values|; null stops. Error(Usage) where the backend cannot (only
  // onednn fp32 can).
  virtual void record_ranges(std::vector<float>* ranges, double quantile = 1.0);

 private:
  virtual void execute(const Image& input, Image& output, const CancelToken* cancel,
                       const std::optional<Rect>& needed) = 0;
};

// Throws residue::Error(Usage) for an unknown or unavailable backend / precision, saying what is available.
std::unique_ptr<Backend> make_backend(const std::string& name, const Graph& graph, const BackendOptions& options);
std::unique_ptr<Backend> make_backend(const std::string& name, const Network& network, const BackendOptions& options);
std::vector<std::string> available_backends();
// Whether this CPU computes bf16 natively (AVX512_BF16 or AMX, as oneDNN finds it): bf16 inference runs only then.
bool bf16_available();
// What runs when the caller names no backend: the faster one for this precision as measured.
std::string default_backend(Precision precision);

std::unique_ptr<Backend> make_eigen_backend(const Graph& graph);
// Whether eigen runs its direct AVX-512 kernel here (the CPU has AVX-512 and RESIDUE_EIGEN_PORTABLE is unset);
// else its portable im2col + GEMM path.
bool eigen_runs_direct_kernel();

}  // namespace residue::nn
