// Loaded models kept for the life of a process (the frames of a sequence, the scenes of an evaluation, a
// viewer's runs): each file is read and checked once. Keyed by the name asked for and the file it resolves to,
// because an alias and its model share a file but not their settings.
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

#include "core/features/feature_set.h"
#include "core/nn/model_file.h"

namespace residue::nn {

class ModelCache {
 public:
  // What load_model_for(name_or_path, available) loads, from the cache when it was loaded before.
  std::shared_ptr<const Model> load(const std::string& name_or_path, FeatureSet available);

 private:
  std::mutex mutex_;
  std::map<std::pair<std::string, std::filesystem::path>, std::shared_ptr<const Model>> models_;
};

}  // namespace residue::nn
