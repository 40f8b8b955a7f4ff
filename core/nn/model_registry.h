// Where models come from, in one place: the model folders, what a name selects for a render's AOVs (a file, a
// family's variant, an alias with its settings, one of Open Image Denoise's networks), and the loaded models,
// each read and checked once for the life of the registry. The CLI (every frame of a sequence, every scene of
// evaluate-set, a farm job), the viewer and the trainer all resolve and load through it; the cards a user picks
// a model by are in model_card.h, made from the same lookups.
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/features/feature_set.h"
#include "core/nn/model_alias.h"
#include "core/nn/model_file.h"

namespace residue::nn {

// Where model names are looked up, in order: $RESIDUE_MODEL_PATH, then each shipped data folder's models/.
std::vector<std::filesystem::path> model_dirs();

// `name_or_path`: an existing file, or a model name looked up in model_dirs(). Throws Error(Input) listing
// where it looked.
std::filesystem::path find_model(const std::string& name_or_path);

// A model *name* names a family of variants, one per feature set: NAME (full), NAME-albedo-normal, NAME-color,
// NAME-variance.
std::string model_variant_name(const std::string& family, FeatureSet set);

// What a name selects for a render.
struct ModelChoice {
  std::string name;                 // as asked for
  std::filesystem::path file;       // the file that runs
  int ensemble = 0;                 // the self-ensemble the name runs with; 0: the model's own
  std::optional<ModelAlias> alias;  // the alias the name is, if it is one
};

// The choice for a render with `available` AOVs: a path is taken as it is; a family name selects the richest
// variant that exists and that a stack able to feed `available` can use, so a render without depth (or without
// any AOV) gets the model trained for what it has instead of zeros; "oidn" picks OIDN's rt_hdr_alb_nrm (with
// albedo and normal) or rt_hdr, "oidn-cleanaux" its final-frame network rt_hdr_calb_cnrm_large (albedo and
// normal needed), both from <model dir>/oidn/; an alias (model_alias.h, e.g. "best") selects its model's
// variant with the alias's settings. Throws Error(Input) listing what was looked for.
ModelChoice resolve_model(const std::string& name_or_path, FeatureSet available);
// resolve_model(...).file.
std::filesystem::path find_model_for(const std::string& name_or_path, FeatureSet available);

// Loads what `name_or_path` selects (resolve_model), with the alias's settings applied, uncached.
Model load_model_for(const std::string& name_or_path, FeatureSet available);

class ModelRegistry {
 public:
  // What load_model_for(name_or_path, available) loads, from the registry when it was loaded before. Keyed by
  // the name and the file, because an alias and its model share a file but not their settings.
  std::shared_ptr<const Model> load(const std::string& name_or_path, FeatureSet available);

  // A family that has a variant for `available` AOVs when `family` has none (a viewer shows a stream with
  // colour only, say): the cheapest Residue family of `families` (in order of cost) that has one. Empty when
  // `family` fits as it is, is not among `families`, or no family fits.
  static std::optional<std::string> substitute(const std::string& family, FeatureSet available,
                                               const std::vector<std::string>& families);

 private:
  std::mutex mutex_;
  std::map<std::pair<std::string, std::filesystem::path>, std::shared_ptr<const Model>> models_;
};

}  // namespace residue::nn
