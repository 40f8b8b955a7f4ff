// What int8 calibration measures (core/nn/calibration.h): every op's range while a model denoises renders in fp32
// on oneDNN (nn::Backend::record_ranges), for `residue-cli calibrate` and for bench's speed-only ranges.
#pragma once

#include <cstddef>
#include <functional>
#include <vector>

#include "core/aov/aov_stack.h"
#include "core/nn/model_file.h"

namespace residue {

// Denoises `count` renders (render(k) gives the k-th; after(k) is called once it is done) with `model` alone (no
// self-ensemble) and returns each op's largest |value|, or with `quantile` < 1 that quantile of each render's
// non-zero |values|, the largest over the renders.
std::vector<float> measure_value_ranges(const nn::Model& model, size_t count,
                                        const std::function<AovStack(size_t)>& render, double quantile = 1.0,
                                        int threads = 0, const std::function<void(size_t)>& after = {});

}  // namespace residue
