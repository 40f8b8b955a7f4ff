#include "core/aov/dataset.h"

#include <algorithm>

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

}  // namespace residue
