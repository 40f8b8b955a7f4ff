#include "core/nn/model_cache.h"

#include "core/nn/model_alias.h"

namespace residue::nn {

std::shared_ptr<const Model> ModelCache::load(const std::string& name_or_path, FeatureSet available) {
  const std::filesystem::path file = find_model_for(name_or_path, available);
  std::lock_guard lock(mutex_);
  auto& slot = models_[{name_or_path, file}];
  if (!slot) slot = std::make_shared<const Model>(load_model_for(name_or_path, available));
  return slot;
}

}  // namespace residue::nn
