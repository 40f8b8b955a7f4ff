#include "core/aov/dataset.h"

#include <algorithm>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "core/util/error.h"

namespace residue {

std::vector<std::filesystem::path> list_dataset_scenes(const std::filesystem::path& root) {
  if (!std::filesystem::is_directory(root))
    throw Error(ErrorKind::Input, "data set '" + root.string() + "' is not a folder");
  std::vector<std::filesystem::path> scenes;
  for (const auto& e : std::filesystem::directory_iterator(root))
    if (e.is_directory() && std::filesystem::exists(e.path() / "noisy_a.exr") &&
        std::filesystem::exists(e.path() / "reference.exr"))
      scenes.push_back(e.path());
  std::sort(scenes.begin(), scenes.end());
  return scenes;
}

DatasetSplit split_dataset(const std::filesystem::path& root, size_t fallback_validation) {
  const auto scenes = list_dataset_scenes(root);
  DatasetSplit out;
  const auto index = root / "index.json";
  if (std::filesystem::exists(index)) {
    std::map<std::string, std::string> split_of;
    try {
      std::ifstream in(index);
      const auto j = nlohmann::json::parse(in);
      for (const auto& s : j.at("scenes")) split_of[s.at("folder").get<std::string>()] = s.at("split").get<std::string>();
    } catch (const std::exception& e) {
      throw Error(ErrorKind::Input, "data set index '" + index.string() + "' is not valid: " + e.what() +
                                        " (expected {\"scenes\": [{\"folder\": ..., \"split\": \"train\" | \"validation\"}]})");
    }
    out.from_index = true;
    for (const auto& s : scenes) {
      const auto it = split_of.find(s.filename().string());
      if (it == split_of.end()) continue;  // not finished when the index was written
      (it->second == "validation" ? out.validation : out.train).push_back(s);
    }
    return out;
  }
  const size_t nval = std::min(fallback_validation, scenes.size() / 2);
  out.train.assign(scenes.begin(), scenes.end() - static_cast<std::ptrdiff_t>(nval));
  out.validation.assign(scenes.end() - static_cast<std::ptrdiff_t>(nval), scenes.end());
  return out;
}

}  // namespace residue
