#include "core/aov/dataset.h"

#include <algorithm>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include <tbb/parallel_for.h>

#include "core/aov/aov_loader.h"
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

Image variance_from_halves(const Image& a, const Image& b) {
  if (a.width() != b.width() || a.height() != b.height() || a.channels() < 3 || b.channels() < 3)
    throw Error(ErrorKind::Usage, "variance_from_halves: the halves must have the same size and >= 3 channels");
  Image var(a.width(), a.height(), 3);
  tbb::parallel_for(int64_t{0}, a.height(), [&](int64_t y) {
    for (int64_t x = 0; x < a.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        const float d = a.at(x, y, c) - b.at(x, y, c);
        var.at(x, y, c) = std::isfinite(d) ? 0.5f * d * d : 0.0f;
      }
  });
  return var;
}

AovStack load_dataset_scene(const std::filesystem::path& scene, bool with_reference) {
  LoadOptions o;
  if (with_reference) o.reference = scene / "reference.exr";
  o.load_reference = with_reference;
  AovStack a = load_aov_stack({scene / "noisy_a.exr"}, o);
  const auto b_path = scene / "noisy_b.exr";
  if (!a.variance && std::filesystem::exists(b_path)) {
    LoadOptions ob;
    ob.load_reference = false;
    const AovStack b = load_aov_stack({b_path}, ob);
    if (b.width() != a.width() || b.height() != a.height())
      throw Error(ErrorKind::Input, "'" + b_path.string() + "' is " + std::to_string(b.width()) + "x" +
                                        std::to_string(b.height()) + ", its other half " + std::to_string(a.width()) +
                                        "x" + std::to_string(a.height()));
    Aov var;
    var.image = variance_from_halves(a.color.image, b.color.image);
    var.source.file = b_path.string();
    var.source.layer = "variance from the two halves, (a - b)^2 / 2";
    a.variance = std::move(var);
  }
  return a;
}

}  // namespace residue
