// FrameSequence: the frames a render belongs to. A render whose file name holds a frame number
// (shot.0042.exr) is one frame of shot.####.exr when its folder holds at least one more frame of that pattern;
// the viewer then steps and plays through them (ui/session.h keeps each frame's results). The reference of each
// frame follows a pattern too: the one the user gave for the first frame when its name holds the same frame
// number, else reference.####.exr beside the frames (the layout of tools/datagen/render_shots.py).
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include "core/io/frame_sequence.h"

namespace residue::ui {

struct FrameSequence {
  io::FramePattern pattern;
  std::vector<int64_t> frames;                 // ascending, every frame found on disk (two or more)
  std::optional<io::FramePattern> reference;   // each frame's reference, when the frames have one

  // The sequence `render` is a frame of, or nullopt (no frame number in its name, or no other frame beside it).
  // `reference`: the reference the user named for this frame, if any.
  static std::optional<FrameSequence> of(const std::filesystem::path& render,
                                         const std::optional<std::filesystem::path>& reference);

  std::filesystem::path input(int64_t frame) const { return pattern.path(frame); }
  std::optional<std::filesystem::path> referenceFor(int64_t frame) const;  // when it exists on disk
  int indexOf(int64_t frame) const;  // -1 when not a frame of the sequence
  bool contains(int64_t frame) const { return indexOf(frame) >= 0; }
};

}  // namespace residue::ui
