// Shots laid out as tools/datagen/render_shots.py writes them (issue 51): one folder per shot (s<seed>/) holding
// noisy.####.exr (every AOV and the motion) and reference.####.exr per frame, and root/index.json with the cut
// into training and validation shots. Shared by the trainer and the sequence evaluation.
#pragma once

#include <filesystem>
#include <vector>

#include "core/aov/aov_stack.h"

namespace residue {

struct ShotSplit {
  std::vector<std::filesystem::path> train, validation;
};
// The shots of root/index.json ("shots": [{"folder": "s8007", "split": "validation"}, ...]) that exist on disk.
// Throws Error(Input) when root has no index.json, it does not parse, or a shot's split is neither.
ShotSplit split_shots(const std::filesystem::path& root);

// The frame numbers of a shot that have both noisy.####.exr and reference.####.exr, ascending.
std::vector<int> shot_frame_numbers(const std::filesystem::path& shot);
std::filesystem::path shot_noisy_path(const std::filesystem::path& shot, int frame);
std::filesystem::path shot_reference_path(const std::filesystem::path& shot, int frame);

// Frame `frame` of a shot with its reference, and the neighbours -radius..+radius the shot has warped to it
// (AovStack::neighbours; core/temporal/frame_window.h). Throws Error(Input) naming the file that is missing or
// unreadable.
AovStack load_shot_frame(const std::filesystem::path& shot, int frame, int radius, bool with_reference = true);

}  // namespace residue
