// Model aliases: a name that stands for another model run a stated way, so that a script or a farm job can ask
// for "the most accurate model measured" (`-m best`) and get whatever the project measures that to be, without
// a second copy of any weights. Each model folder may hold an aliases.json:
//   {"best": {"model": "base", "ensemble": 8, "description": "...",
//             "validation": {"relmse": 0.0088, "ssim": 0.941, "scenes": 30}}}
// "model" is a family name (resolved per render like any name, variants included) or "oidn"; "ensemble" (1, 2,
// 4 or 8; optional) overrides the model's own self-ensemble; "validation" and "benchmark" are what was measured
// for the alias as it runs (its card shows those, not the target's). The first folder that defines a name wins, as for
// models; an alias hides a model file of the same name in any folder (name aliases apart from models).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "core/features/feature_set.h"
#include "core/nn/model_file.h"

namespace residue::nn {

struct ModelAlias {
  std::string name;         // what -m takes
  std::string model;        // the family it stands for
  int ensemble = 0;         // 0: the model's own
  std::string description;
  std::string validation;   // JSON text as in a model file's "validation" metadata (empty: none measured)
  std::string benchmark;    // likewise, its "benchmark" (seconds per megapixel as the alias runs)
  std::filesystem::path file;  // the aliases.json that defines it
};

// The alias `name` defines, if any folder of model_dirs() does. Throws Error(Input) naming the file when an
// aliases.json cannot be read or an entry is malformed (a bad ensemble, a missing "model"); find_model_for
// refuses an alias whose model is itself an alias.
std::optional<ModelAlias> find_model_alias(const std::string& name);
// Every alias, the first definition of each name; unreadable files are left out with a line in `problems`.
std::vector<ModelAlias> list_model_aliases(std::vector<std::string>* problems = nullptr);

}  // namespace residue::nn
