// The methods Residue knows, keyed by family name: "residue" (its residual networks, .safetensors), "temporal"
// (those of them that read a shot's neighbouring frames), "oidn" (Open Image Denoise's networks, .tza) and
// "bilateral" (the filter, no model file). Adding a method is one
// file that implements Method (method.h) and one line in the table (method_registry.cpp), or a
// register_method() call (a plug-in, a test).
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "core/denoise/method.h"
#include "core/features/feature_set.h"
#include "core/nn/model_registry.h"
#include "core/nn/model_file.h"

namespace residue {

struct MethodEntry {
  std::string family;   // the name `-m` takes for a method without a model; a model's kind otherwise
  std::string summary;  // one line for listings
  bool needs_model = true;  // false: `-m FAMILY` runs it as it is (the bilateral filter)
  // Makes the method for a loaded model of this family (null for a method without a model).
  std::function<std::unique_ptr<Method>(std::shared_ptr<const nn::Model>)> make;
};

// Adds a method (or replaces the one of the same family).
void register_method(MethodEntry entry);
// The entry of `family`, or null.
const MethodEntry* find_method(std::string_view family);
std::vector<std::string> method_families();

// The method that runs a loaded model: the entry of the model's kind (nn::Model::method; "temporal" for a
// Residue network that reads neighbouring frames).
std::unique_ptr<Method> make_method(std::shared_ptr<const nn::Model> model);
// A model-free method by family name ("bilateral"); Error(Usage) listing the known ones otherwise.
std::unique_ptr<Method> make_method(std::string_view family);
// Whether `name` is a method that needs no model file (then make_method(name) makes it).
bool is_model_free_method(std::string_view name);

// The method `-m NAME` asks for on a render with `available` AOVs: a model-free method by its name, else the
// model the name (a file, a family, an alias) selects for those AOVs, loaded through `models`. Throws
// Error(Input) when no model file fits, listing what was looked for.
std::unique_ptr<Method> resolve_method(const std::string& name_or_path, FeatureSet available, nn::ModelRegistry& models);

// The factories of the built-in methods, one file each.
std::unique_ptr<Method> make_residue_method(std::shared_ptr<const nn::Model> model);
std::unique_ptr<Method> make_oidn_method(std::shared_ptr<const nn::Model> model);
std::unique_ptr<Method> make_bilateral_method(std::shared_ptr<const nn::Model> model);
std::unique_ptr<Method> make_temporal_method(std::shared_ptr<const nn::Model> model);

}  // namespace residue
