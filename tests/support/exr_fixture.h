// Writing EXR files for loader tests directly with OpenImageIO (independent of core/io, which is under test
// elsewhere): any channel names, half or float per channel, data windows, several parts.
#pragma once

#include <array>
#include <functional>
#include <string>
#include <vector>

namespace residue::testing {

struct FixtureChannel {
  std::string name;
  bool half = false;
  // Value at (x, y) in display coordinates.
  std::function<float(int, int)> value;
};

struct FixturePart {
  std::string name;  // part name (multipart files); empty for single-part
  std::vector<FixtureChannel> channels;
  int x = 0, y = 0, width = 0, height = 0;  // data window
  int full_width = 0, full_height = 0;      // display window (0 = data window size)
  std::vector<std::pair<std::string, std::string>> string_attributes;
  std::vector<std::pair<std::string, std::array<float, 16>>> matrix_attributes;  // 4x4 (M44f), row-major
  std::vector<std::pair<std::string, int>> int_attributes;
};

// Writes one file with one or more parts; throws std::runtime_error on failure.
void write_fixture_exr(const std::string& path, const std::vector<FixturePart>& parts);

// A constant-valued channel.
FixtureChannel constant_channel(const std::string& name, float value, bool half = false);

// The value the loader should produce for a half channel written with `value`.
float as_half(float value);

}  // namespace residue::testing
