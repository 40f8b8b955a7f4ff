// Frame-numbered file names as renderers, compositors and farm managers write them:
//   shot.####.exr     one '#' per digit, zero-padded (shot.0042.exr; wider numbers are written as they are)
//   shot.%04d.exr     printf style (%d: no padding)
// and frame specs as farm managers take them: "1001-1100", "1001-1100x2" (every 2nd), "1,5,7-20:2".
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace residue::io {

struct FramePattern {
  std::string prefix;  // before the frame number, folder included
  std::string suffix;  // after it
  int width = 0;       // zero-padded to this many digits (0 or 1: no padding)

  // The pattern of `text`, or nullopt when it names no frame (a plain file name). Error(Usage) for a name with
  // two frame fields.
  static std::optional<FramePattern> parse(const std::string& text);
  // The pattern a frame's own file belongs to, as image viewers find sequences: the last run of digits in the
  // file name is the frame number ("shot.0042.exr" -> "shot.####.exr", "beauty_7.exr" -> "beauty_#.exr"); nullopt
  // when the name has no digits.
  static std::optional<FramePattern> of_numbered_file(const std::string& file);
  std::filesystem::path path(int64_t frame) const;
  std::string to_string() const;  // with '#'s, e.g. "out/shot.####.exr"
  // The frame number of `file` (a path written by path()), or nullopt when it does not match.
  std::optional<int64_t> frame_of(const std::string& file) const;
};

// The frames of a spec, in the order given, without repeats. Error(Usage) naming the part that is malformed
// (negative frames, an empty range, a step below 1, more than 10 million frames).
std::vector<int64_t> parse_frame_spec(const std::string& spec);

// The frames whose file exists, ascending (one listing of the pattern's folder).
std::vector<int64_t> find_frames(const FramePattern& pattern);

}  // namespace residue::io
