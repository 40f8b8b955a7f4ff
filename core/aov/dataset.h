// Data sets laid out like ../shared/datasets/cycles-starter: one folder per scene (s<seed>/) holding
// noisy_a.exr (+ noisy_b.exr, the second independent half) and reference.exr. Shared by the trainer and
// `residue-cli evaluate-set`.
#pragma once

#include <filesystem>
#include <vector>

#include "core/aov/aov_stack.h"

namespace residue {

// Scene folders under `root` that hold noisy_a.exr and reference.exr, sorted by name.
// Throws Error(Input) when `root` is not a folder.
std::vector<std::filesystem::path> list_dataset_scenes(const std::filesystem::path& root);

// A data set cut into training and validation scenes. The project's data sets (tools/datagen) carry the cut in
// root/index.json ("scenes": [{"folder": "s1010", "split": "validation"}, ...]); it is used when present, for
// the scenes that exist. Otherwise the last `fallback_validation` scenes by name (at most half) are validation.
struct DatasetSplit {
  std::vector<std::filesystem::path> train, validation;
  bool from_index = false;
};
// Throws Error(Input) when `root` is not a folder or its index.json does not parse.
DatasetSplit split_dataset(const std::filesystem::path& root, size_t fallback_validation);

// Per-pixel variance of each of two independent renders of the same pixels (a and b, same spp): the
// difference of two independent estimates has twice their variance, so var = (a - b)^2 / 2, per RGB channel.
// Non-finite differences give 0. Throws Error(Usage) unless both have the same size and >= 3 channels.
Image variance_from_halves(const Image& a, const Image& b);

// One scene of a data set as the network sees it: noisy_a.exr with its AOVs and reference.exr; when
// noisy_b.exr exists (and noisy_a has no variance AOV of its own), the colour's variance from the two halves.
AovStack load_dataset_scene(const std::filesystem::path& scene, bool with_reference = true);

}  // namespace residue
