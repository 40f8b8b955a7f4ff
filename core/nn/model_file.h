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
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/features/feature_set.h"
#include "core/nn/backend.h"
#include "core/nn/network.h"
#include "core/nn/safetensors.h"

namespace residue::nn {

// How a model's network is fed and read: Residue's own models (log features in, log colour out, post-steps),
// or Open Image Denoise's networks run as OIDN runs them (core/denoise/oidn_filter.h), for comparison. Bilateral:
// the cross-bilateral filter, a method with no network (only a model card has it, core/nn/model_card.h).
enum class Method { Residue, Oidn, Bilateral };

// What an OIDN network takes, from its file name (rt_hdr_alb_nrm, rt_hdr_calb_cnrm_large, rt_alb_large, ...).
struct OidnInputs {
  bool color = true, albedo = false, normal = false;
  bool hdr = true;
  bool clean_aux = false;  // albedo and normal are expected noise-free (prefiltered)
};

struct Model {
  std::string name;   // metadata "name", else the file's stem
  std::string path;
  std::map<std::string, std::string> metadata;
  Method method = Method::Residue;
  Network network;    // Residue models: the ResNet, batch norm folded
  Graph graph;        // what the backends run (every model)
  OidnInputs oidn;    // OIDN models
  // OIDN's final-frame mode (clean_aux): the networks that denoise the albedo and the normal first.
  std::shared_ptr<const Model> albedo_prefilter, normal_prefilter;
  // A post-correction model's prior (Architecture::prior): the network whose output it refines, run first.
  std::shared_ptr<const Model> prior;
  // The self-ensemble it runs with unless told otherwise (metadata residue.ensemble: 1, 2, 4 or 8 flips and
  // transposes averaged; DenoiseOptions::ensemble).
  int ensemble = 1;
  // Its int8 calibration (calibration.h), read from beside the file into graph's ranges: what it was measured on.
  // Empty: none, and the model runs fp32 and bf16 only.
  std::string int8_calibration;

  FeatureSet features() const;  // the AOVs a Residue model reads (OIDN: the nearest set)
  std::string architecture() const;  // "8/32 full", "OIDN UNet (rt_hdr_alb_nrm)"
};

// A Residue model from a network in memory (tests, benchmarks): its graph made from it.
Model model_from_network(Network network, std::string name = "in-memory");

// Loads and checks a model: every tensor's name, shape and dtype; throws Error(Input) naming the file and the
// tensor on any mismatch (missing, unexpected, wrong shape, truncated file). A .tza file is one of Open Image
// Denoise's networks (its inputs read from the name; clean-aux ones load their prefilters from beside them).
Model load_model(const std::filesystem::path& path);

// The model a denoise runs when none is named (the CLI, the viewer): the best speed/accuracy trade measured
// (docs/MODELS.md).
inline constexpr const char* kDefaultModel = "multiscale";
// What `denoise --temporal` runs unless -m names another temporal model (docs/TEMPORAL.md).
inline constexpr const char* kDefaultTemporalModel = "multiscale-temporal";

// Finding a model by name (model folders, variants, aliases) and loading it once: model_registry.h.

// A network as a model file's tensors (batch norm written as identity: the weights are already folded).
SafetensorsFile to_safetensors(const Network& network, std::map<std::string, std::string> metadata = {});
// The residue.* keys that describe `arch` (what load_model reads back), written into `metadata`: one writer for
// core's files and the trainer's.
void write_architecture_metadata(const Architecture& arch, std::map<std::string, std::string>& metadata);

}  // namespace residue::nn
