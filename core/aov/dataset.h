// Data sets laid out like ../shared/datasets/cycles-starter: one folder per scene (s<seed>/) holding
// noisy_a.exr (+ noisy_b.exr, the second independent half) and reference.exr. Shared by the trainer and
// `residue-cli evaluate-set`.
#pragma once

#include <filesystem>
#include <vector>

namespace residue {

// Scene folders under `root` that hold noisy_a.exr and reference.exr, sorted by name.
// Throws Error(Input) when `root` is not a folder.
std::vector<std::filesystem::path> list_dataset_scenes(const std::filesystem::path& root);

}  // namespace residue
