#include "core/nn/model_registry.h"

#include <algorithm>
#include <cstdlib>

#include "core/nn/model_card.h"

#include "core/util/error.h"
#include "core/util/input_file.h"
#include "core/util/resources.h"

namespace residue::nn {

std::vector<std::filesystem::path> model_dirs() {
  std::vector<std::filesystem::path> dirs;
  if (const char* env = std::getenv("RESIDUE_MODEL_PATH")) dirs.emplace_back(env);
  for (const auto& d : resource_dirs()) dirs.push_back(d / "models");
  return dirs;
}

std::filesystem::path find_model(const std::string& name_or_path) {
  if (std::filesystem::is_regular_file(name_or_path)) return name_or_path;
  std::string looked;
  for (const auto& d : model_dirs()) {
    const auto candidate = d / (name_or_path + ".safetensors");
    if (std::filesystem::is_regular_file(candidate)) return candidate;
    looked += " " + d.string();
  }
  throw Error(ErrorKind::Input, "model \"" + name_or_path + "\" is neither a file nor a model name found in:" + looked);
}

std::string model_variant_name(const std::string& family, FeatureSet set) {
  switch (set) {
    case FeatureSet::Full: return family;
    case FeatureSet::ColorAlbedoNormal: return family + "-albedo-normal";
    case FeatureSet::ColorOnly: return family + "-color";
    case FeatureSet::FullVariance: return family + "-variance";
  }
  return family;
}

ModelChoice resolve_model(const std::string& name_or_path, FeatureSet available) {
  ModelChoice choice;
  choice.name = name_or_path;
  std::error_code ec;
  if (std::filesystem::is_regular_file(name_or_path, ec)) {
    choice.file = name_or_path;
    return choice;
  }
  // A path (a folder in it, or a model file's extension) is a file the user named: say what is wrong with it
  // rather than looking for a model of that name.
  const std::string extension = std::filesystem::path(name_or_path).extension().string();
  if (name_or_path.find('/') != std::string::npos || extension == ".safetensors" || extension == ".tza")
    check_input_file(name_or_path, "model file");
  if (const auto alias = find_model_alias(name_or_path)) {
    // One level only: an alias of an alias could loop, and what runs should be one lookup away from the name.
    if (find_model_alias(alias->model))
      throw Error(ErrorKind::Input, alias->file.string() + ": alias \"" + alias->name + "\" stands for \"" +
                                        alias->model + "\", which is itself an alias; name a model");
    choice.file = resolve_model(alias->model, available).file;
    choice.ensemble = alias->ensemble;
    choice.alias = alias;
    return choice;
  }
  if (name_or_path == "oidn" || name_or_path == "oidn-cleanaux") {
    const bool aux = feature_channels(available) >= feature_channels(FeatureSet::ColorAlbedoNormal);
    std::string file = aux ? "rt_hdr_alb_nrm" : "rt_hdr";
    if (name_or_path == "oidn-cleanaux") {
      if (!aux)
        throw Error(ErrorKind::Input, "model \"oidn-cleanaux\" needs albedo and normal AOVs, which this render lacks");
      file = "rt_hdr_calb_cnrm_large";
    }
    std::string looked;
    for (const auto& d : model_dirs()) {
      if (std::filesystem::is_regular_file(d / "oidn" / (file + ".tza"))) {
        choice.file = d / "oidn" / (file + ".tza");
        return choice;
      }
      looked += " " + (d / "oidn").string();
    }
    throw Error(ErrorKind::Input, "Open Image Denoise's network " + file + ".tza is not installed (looked in:" +
                                      looked + "); tools/dev/fetch_oidn_weights.sh --install fetches it");
  }
  std::vector<FeatureSet> usable;
  for (FeatureSet s : {FeatureSet::FullVariance, FeatureSet::Full, FeatureSet::ColorAlbedoNormal, FeatureSet::ColorOnly})
    if (feature_channels(s) <= feature_channels(available)) usable.push_back(s);  // the sets nest: 10 > 9 > 8 > 3
  std::string tried;
  for (FeatureSet s : usable) {
    const std::string name = model_variant_name(name_or_path, s);
    for (const auto& d : model_dirs())
      if (std::filesystem::is_regular_file(d / (name + ".safetensors"))) {
        choice.file = d / (name + ".safetensors");
        return choice;
      }
    tried += (tried.empty() ? "" : ", ") + name;
  }
  std::string looked;
  for (const auto& d : model_dirs()) looked += " " + d.string();
  auto has = [&](FeatureSet s) {
    switch (s) {
      case FeatureSet::FullVariance: return "colour, albedo, normal, depth and variance";
      case FeatureSet::Full: return "colour, albedo, normal and depth";
      case FeatureSet::ColorAlbedoNormal: return "colour, albedo and normal (no depth)";
      case FeatureSet::ColorOnly: return "colour only (no complete albedo and normal)";
    }
    return "";
  };
  throw Error(ErrorKind::Input, "no model \"" + name_or_path + "\" for the AOVs this render has: " + has(available) +
                                    "; tried " + tried + " in:" + looked);
}

std::filesystem::path find_model_for(const std::string& name_or_path, FeatureSet available) {
  return resolve_model(name_or_path, available).file;
}

Model load_model_for(const std::string& name_or_path, FeatureSet available) {
  const ModelChoice choice = resolve_model(name_or_path, available);
  Model m = load_model(choice.file);
  if (choice.ensemble > 0) m.ensemble = choice.ensemble;
  return m;
}

std::shared_ptr<const Model> ModelRegistry::load(const std::string& name_or_path, FeatureSet available) {
  const ModelChoice choice = resolve_model(name_or_path, available);
  std::lock_guard lock(mutex_);
  auto& slot = models_[{name_or_path, choice.file}];
  if (!slot) {
    Model m = load_model(choice.file);
    if (choice.ensemble > 0) m.ensemble = choice.ensemble;
    slot = std::make_shared<const Model>(std::move(m));
  }
  return slot;
}

std::optional<std::string> ModelRegistry::substitute(const std::string& family, FeatureSet available,
                                                     const std::vector<std::string>& families) {
  if (std::find(families.begin(), families.end(), family) == families.end()) return std::nullopt;
  try {
    (void)resolve_model(family, available);
    return std::nullopt;  // it fits as it is
  } catch (const Error&) {
  }
  for (const std::string& f : families) {
    if (method_of(f) != Method::Residue || find_model_alias(f)) continue;
    try {
      (void)resolve_model(f, available);
      return f;
    } catch (const Error&) {
    }
  }
  return std::nullopt;
}

}  // namespace residue::nn
