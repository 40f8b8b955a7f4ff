// Model files: the network's weights in safetensors, the architecture and feature set in the metadata.
//
// Tensor names follow PyTorch module naming, so a libtorch/PyTorch state_dict exports as is:
//   head.conv.weight [W, C_in, 3, 3]  head.conv.bias [W]  head.prelu.weight [W]
//   blocks.{i}.conv1.weight [W, W, 3, 3]  blocks.{i}.bn1.{weight,bias,running_mean,running_var} [W]
//   blocks.{i}.prelu.weight [W]  blocks.{i}.conv2.weight [W, W, 3, 3]  blocks.{i}.bn2.* [W]
//   tail.conv.weight [W, W, 3, 3]  tail.bn.* [W]
//   out.conv.weight [3, W, 3, 3]  out.conv.bias [3]
// Metadata (strings): residue.format = "1", residue.blocks, residue.width, residue.features ("full",
// "color+albedo+normal", "color"), residue.bn_eps; free-form: name, description, training, validation
// (JSON text, e.g. {"relmse": 0.0031, "ssim": 0.95}).
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/features/feature_set.h"
#include "core/nn/network.h"
#include "core/nn/safetensors.h"

namespace residue::nn {

struct Model {
  std::string name;   // metadata "name", else the file's stem
  std::string path;
  std::map<std::string, std::string> metadata;
  Network network;    // batch norm folded
};

// Loads and checks a model: every tensor's name, shape and dtype; throws Error(Input) naming the file and the
// tensor on any mismatch (missing, unexpected, wrong shape, truncated file).
Model load_model(const std::filesystem::path& path);

// `name_or_path`: an existing file, or a model name looked up in $RESIDUE_MODEL_PATH, the source tree's
// resources/models and <prefix>/share/residue/models. Throws Error(Input) listing where it looked.
std::filesystem::path find_model(const std::string& name_or_path);
// Where model names are looked up, in order: $RESIDUE_MODEL_PATH, then each shipped data folder's models/.
std::vector<std::filesystem::path> model_dirs();

// A model *name* names a family of variants, one per feature set: NAME (full), NAME-albedo-normal, NAME-color.
// Returns the richest variant that exists and that a stack able to feed `available` can use, so a render
// without depth (or without any AOV) gets the model trained for what it has instead of zeros.
// A path is returned as is. Throws Error(Input) listing what was looked for.
std::filesystem::path find_model_for(const std::string& name_or_path, FeatureSet available);
std::string model_variant_name(const std::string& family, FeatureSet set);

// A network as a model file's tensors (batch norm written as identity: the weights are already folded).
SafetensorsFile to_safetensors(const Network& network, std::map<std::string, std::string> metadata = {});

}  // namespace residue::nn
