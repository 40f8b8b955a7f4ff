#include "core/aov/shot_dataset.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>

#include <nlohmann/json.hpp>

#include "core/aov/aov_loader.h"
#include "core/temporal/frame_window.h"
#include "core/util/error.h"

namespace residue {
namespace fs = std::filesystem;

namespace {

fs::path frame_file(const fs::path& shot, const char* prefix, int frame) {
  char name[64];
  std::snprintf(name, sizeof name, "%s.%04d.exr", prefix, frame);
  return shot / name;
}

}  // namespace

fs::path shot_noisy_path(const fs::path& shot, int frame) { return frame_file(shot, "noisy", frame); }
fs::path shot_reference_path(const fs::path& shot, int frame) { return frame_file(shot, "reference", frame); }

ShotSplit split_shots(const fs::path& root) {
  const fs::path index = root / "index.json";
  std::ifstream in(index);
  if (!in) throw Error(ErrorKind::Input, "'" + index.string() + "' cannot be read: a shot data set lists its shots there");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::exception& e) {
    throw Error(ErrorKind::Input, "'" + index.string() + "' does not parse: " + e.what());
  }
  ShotSplit split;
  for (const auto& s : j.value("shots", nlohmann::json::array())) {
    const fs::path dir = root / s.value("folder", "");
    const std::string which = s.value("split", "");
    if (which != "train" && which != "validation")
      throw Error(ErrorKind::Input, "'" + index.string() + "': shot '" + s.value("folder", "") + "' has split '" + which +
                                    "'; expected train or validation");
    if (!fs::is_directory(dir)) continue;
    (which == "train" ? split.train : split.validation).push_back(dir);
  }
  return split;
}

std::vector<int> shot_frame_numbers(const fs::path& shot) {
  std::vector<int> frames;
  if (!fs::is_directory(shot)) throw Error(ErrorKind::Input, "'" + shot.string() + "' is not a folder");
  for (const auto& e : fs::directory_iterator(shot)) {
    const std::string name = e.path().filename().string();
    int frame = 0;
    char tail[8] = {};
    if (std::sscanf(name.c_str(), "noisy.%d.%4s", &frame, tail) == 2 && std::string(tail) == "exr" &&
        name == shot_noisy_path(shot, frame).filename().string() && fs::exists(shot_reference_path(shot, frame)))
      frames.push_back(frame);
  }
  std::sort(frames.begin(), frames.end());
  return frames;
}

AovStack load_shot_frame(const fs::path& shot, int frame, int radius, bool with_reference) {
  auto load = [&](int f, bool reference) {
    LoadOptions o;
    o.load_reference = reference;
    if (reference) o.reference = shot_reference_path(shot, f);
    return load_aov_stack({shot_noisy_path(shot, f)}, o);
  };
  AovStack t = load(frame, with_reference);
  std::map<int, AovStack> near;
  for (int d : neighbour_offsets(radius))
    if (fs::exists(shot_noisy_path(shot, frame + d))) near.emplace(d, load(frame + d, false));
  attach_neighbours(t, radius, [&](int d) -> const AovStack* {
    const auto it = near.find(d);
    return it == near.end() ? nullptr : &it->second;
  });
  return t;
}

}  // namespace residue
