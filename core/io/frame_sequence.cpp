#include "core/io/frame_sequence.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <set>

#include "core/util/error.h"

namespace residue::io {
namespace fs = std::filesystem;
namespace {

[[noreturn]] void bad_spec(const std::string& spec, const std::string& why) {
  throw Error(ErrorKind::Usage, "frame spec \"" + spec + "\": " + why +
                                    " (expected e.g. 1001-1100, 1001-1100x2 or 1,5,7-20:2)");
}

int64_t parse_frame(const std::string& spec, std::string_view text) {
  int64_t v = -1;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty() || v < 0)
    bad_spec(spec, "\"" + std::string(text) + "\" is not a frame number (0 or more)");
  return v;
}

}  // namespace

std::optional<FramePattern> FramePattern::parse(const std::string& text) {
  // Only the file name holds the frame field (a folder named "v#1" stays a folder).
  const auto slash = text.rfind('/');
  const size_t name_start = slash == std::string::npos ? 0 : slash + 1;
  std::optional<FramePattern> found;
  auto take = [&](size_t begin, size_t end, int digits) {
    if (found) throw Error(ErrorKind::Usage, "'" + text + "' has more than one frame-number field");
    found = FramePattern{text.substr(0, begin), text.substr(end), digits};
  };
  for (size_t i = name_start; i < text.size();) {
    if (text[i] == '#') {
      size_t j = i;
      while (j < text.size() && text[j] == '#') ++j;
      take(i, j, static_cast<int>(j - i));
      i = j;
    } else if (text[i] == '%') {
      size_t j = i + 1;
      int width = 0;
      if (j < text.size() && text[j] == '0') ++j;
      while (j < text.size() && std::isdigit(static_cast<unsigned char>(text[j]))) width = width * 10 + (text[j++] - '0');
      if (j < text.size() && text[j] == 'd') {
        take(i, j + 1, width);
        i = j + 1;
      } else {
        ++i;
      }
    } else {
      ++i;
    }
  }
  return found;
}

std::optional<FramePattern> FramePattern::of_numbered_file(const std::string& file) {
  const auto slash = file.rfind('/');
  const size_t name_start = slash == std::string::npos ? 0 : slash + 1;
  size_t end = file.size();
  while (end > name_start && !std::isdigit(static_cast<unsigned char>(file[end - 1]))) --end;
  if (end == name_start) return std::nullopt;
  size_t begin = end;
  while (begin > name_start && std::isdigit(static_cast<unsigned char>(file[begin - 1]))) --begin;
  if (end - begin > 9) return std::nullopt;  // a date or an id, not a frame
  return FramePattern{file.substr(0, begin), file.substr(end), static_cast<int>(end - begin)};
}

fs::path FramePattern::path(int64_t frame) const {
  std::string digits = std::to_string(frame);
  if (static_cast<int>(digits.size()) < width) digits.insert(0, static_cast<size_t>(width) - digits.size(), '0');
  return prefix + digits + suffix;
}

std::string FramePattern::to_string() const { return prefix + std::string(static_cast<size_t>(std::max(width, 1)), '#') + suffix; }

std::optional<int64_t> FramePattern::frame_of(const std::string& file) const {
  if (file.size() <= prefix.size() + suffix.size() || file.compare(0, prefix.size(), prefix) != 0 ||
      file.compare(file.size() - suffix.size(), suffix.size(), suffix) != 0)
    return std::nullopt;
  const std::string digits = file.substr(prefix.size(), file.size() - prefix.size() - suffix.size());
  if (digits.empty() || digits.size() > 15 || !std::all_of(digits.begin(), digits.end(), [](unsigned char c) { return std::isdigit(c); }))
    return std::nullopt;
  // Zero padding exactly as path() writes it: "0042" for width 4, "12345" beyond it, never "042".
  const int64_t frame = std::stoll(digits);
  if (path(frame).string() != file) return std::nullopt;
  return frame;
}

std::vector<int64_t> parse_frame_spec(const std::string& spec) {
  constexpr int64_t kMaxFrames = 10'000'000;
  std::vector<int64_t> frames;
  std::set<int64_t> seen;
  size_t start = 0;
  if (spec.empty()) bad_spec(spec, "empty");
  while (start <= spec.size()) {
    const size_t comma = std::min(spec.find(',', start), spec.size());
    const std::string part = spec.substr(start, comma - start);
    if (part.empty()) bad_spec(spec, "an empty part");
    int64_t first = 0, last = 0, step = 1;
    const size_t dash = part.find('-');
    if (dash == std::string::npos) {
      first = last = parse_frame(spec, part);
    } else {
      const size_t step_at = part.find_first_of("x:", dash);
      first = parse_frame(spec, std::string_view(part).substr(0, dash));
      last = parse_frame(spec, std::string_view(part).substr(dash + 1, step_at == std::string::npos ? std::string::npos : step_at - dash - 1));
      if (step_at != std::string::npos) step = parse_frame(spec, std::string_view(part).substr(step_at + 1));
      if (step < 1) bad_spec(spec, "step " + std::to_string(step) + " in \"" + part + "\" is below 1");
      if (last < first) bad_spec(spec, "\"" + part + "\" ends before it starts");
    }
    if ((last - first) / step + static_cast<int64_t>(frames.size()) >= kMaxFrames) bad_spec(spec, "more than 10 million frames");
    for (int64_t f = first; f <= last; f += step)
      if (seen.insert(f).second) frames.push_back(f);
    start = comma + 1;
  }
  return frames;
}

std::vector<int64_t> find_frames(const FramePattern& pattern) {
  const fs::path probe = pattern.path(0);
  const fs::path folder = probe.has_parent_path() ? probe.parent_path() : fs::path(".");
  std::vector<int64_t> frames;
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path candidate = probe.has_parent_path() ? folder / it->path().filename() : it->path().filename();
    if (auto f = pattern.frame_of(candidate.string())) frames.push_back(*f);
  }
  std::sort(frames.begin(), frames.end());
  return frames;
}

}  // namespace residue::io
