// Model cards: what a user picks a denoiser by, typed. One card per family a name selects (`tiny`, `small`, ...,
// `oidn`, `oidn-cleanaux`, `bilateral`): how it makes its pixels (the method), its architecture and cost from
// its graph, the feature-set variants present, and the validation and benchmark numbers measured for it (model
// file metadata for Residue's models; resources/models/oidn/cards.json for Intel's networks, whose files carry
// none of ours). The viewer's model table and `residue-cli models` read these; nothing else parses that JSON.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/nn/model_file.h"

namespace residue::nn {

// How a family name makes its pixels: "bilateral" -> Bilateral, "oidn" / "oidn-cleanaux" -> Oidn, any other
// name -> Residue (a model file).
Method method_of(std::string_view family);
const char* to_string(Method m);

struct ModelCard {
  struct Validation {
    double relmse = 0, ssim = 0;
    std::optional<double> noisy_relmse;
    int scenes = 0;
  };
  struct Benchmark {
    std::optional<double> fp32_s_per_mp, bf16_s_per_mp;
    std::string machine;  // the CPU it was measured on
  };

  std::string family;  // what find_model_for takes
  std::string alias_of;  // an alias's (core/nn/model_alias.h): the family it stands for; empty for a model
  Method method = Method::Residue;
  std::filesystem::path file;  // the richest variant's file (empty for the bilateral filter)
  std::string architecture;    // "8/32", "3 levels 2,2,4/32,48,64", "OIDN UNet", "cross-bilateral filter"
  int ensemble = 1;            // the self-ensemble it runs with (its cost and numbers are for all its members)
  double gflop_per_mp = 0;     // network work per megapixel (the model's self-ensemble, prefilters and a
                               // post-correction's prior included)
  int reach_px = 0;            // networks: how far an output pixel sees into the input, each side (pixels)
  std::vector<std::string> variants;  // feature sets present: "full", "color+albedo+normal", "color", ...
  std::string description;
  std::optional<Validation> validation;
  std::optional<Benchmark> benchmark;
  std::optional<float> blend_tau;  // Residue models: the variance blend's tau fitted for it

  std::optional<double> seconds_per_mp(Precision p) const;
};

// The card of a loaded model (a Residue model file, or one of OIDN's with its cards.json entry beside it).
ModelCard model_card(const Model& model, const std::string& family);

// Every family found in model_dirs() (the first folder that has a family wins, as find_model) and every alias,
// sorted by cost, the bilateral filter first and OIDN's networks (when installed) last. An alias's card is its
// model's as the alias runs it (ensemble, cost), with the alias's own description and measured numbers. Files
// that cannot be read are left out with a line in `problems`.
std::vector<ModelCard> list_model_cards(std::vector<std::string>* problems = nullptr);

}  // namespace residue::nn
