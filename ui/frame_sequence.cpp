#include "ui/frame_sequence.h"

#include <algorithm>

namespace residue::ui {

namespace fs = std::filesystem;

std::optional<FrameSequence> FrameSequence::of(const fs::path& render, const std::optional<fs::path>& reference) {
  std::error_code ec;
  if (!fs::is_regular_file(render, ec)) return std::nullopt;
  const std::optional<io::FramePattern> pattern = io::FramePattern::of_numbered_file(render.string());
  if (!pattern) return std::nullopt;
  const std::optional<int64_t> frame = pattern->frame_of(render.string());
  if (!frame) return std::nullopt;
  FrameSequence s;
  s.pattern = *pattern;
  s.frames = io::find_frames(*pattern);
  if (s.frames.size() < 2 || !s.contains(*frame)) return std::nullopt;

  if (reference) {
    // A reference named for this frame is a pattern when it holds the same frame number.
    if (auto r = io::FramePattern::of_numbered_file(reference->string()); r && r->frame_of(reference->string()) == frame)
      s.reference = r;
  } else {
    io::FramePattern beside = *pattern;
    beside.prefix = (render.parent_path() / "reference.").string();
    if (render.parent_path().empty()) beside.prefix = "reference.";
    if (fs::is_regular_file(beside.path(*frame), ec) && !fs::equivalent(beside.path(*frame), render, ec))
      s.reference = beside;
  }
  return s;
}

std::optional<fs::path> FrameSequence::referenceFor(int64_t frame) const {
  if (!reference) return std::nullopt;
  std::error_code ec;
  const fs::path p = reference->path(frame);
  if (!fs::is_regular_file(p, ec)) return std::nullopt;
  return p;
}

int FrameSequence::indexOf(int64_t frame) const {
  const auto it = std::lower_bound(frames.begin(), frames.end(), frame);
  return it != frames.end() && *it == frame ? static_cast<int>(it - frames.begin()) : -1;
}

}  // namespace residue::ui
