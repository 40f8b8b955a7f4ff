#include "core/denoise/value_ranges.h"

#include "core/denoise/denoiser.h"

namespace residue {

std::vector<float> measure_value_ranges(const nn::Model& model, size_t count,
                                        const std::function<AovStack(size_t)>& render, double quantile, int threads,
                                        const std::function<void(size_t)>& after) {
  BackendCache backends;
  std::vector<float> ranges;
  backends.get(model, "onednn", nn::Precision::FP32).record_ranges(&ranges, quantile);
  DenoiseOptions options;
  options.backend = "onednn";
  options.precision = nn::Precision::FP32;
  options.ensemble = 1;
  options.threads = threads;
  options.backends = &backends;
  for (size_t k = 0; k < count; ++k) {
    (void)denoise(render(k), model, options);
    if (after) after(k);
  }
  return ranges;
}

}  // namespace residue
