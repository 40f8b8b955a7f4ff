#include "core/nn/model_alias.h"

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/nn/model_registry.h"
#include "core/util/error.h"

namespace residue::nn {
namespace {

// The aliases one file defines; throws Error(Input) naming the file and the entry on anything malformed.
std::vector<ModelAlias> read_aliases(const std::filesystem::path& file) {
  std::ifstream in(file);
  nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  const std::string where = file.string();
  if (!j.is_object())
    throw Error(ErrorKind::Input, where + ": not a JSON object of aliases ({\"best\": {\"model\": \"base\", ...}})");
  std::vector<ModelAlias> out;
  for (const auto& [name, e] : j.items()) {
    const std::string entry = where + ": alias \"" + name + "\"";
    if (!e.is_object() || !e.contains("model") || !e["model"].is_string() || e["model"].get<std::string>().empty())
      throw Error(ErrorKind::Input, entry + " needs \"model\": the name of the model it stands for");
    ModelAlias a;
    a.name = name;
    a.model = e["model"].get<std::string>();
    a.file = file;
    if (e.contains("ensemble")) {
      const auto& n = e["ensemble"];
      if (!n.is_number_integer() || (n != 1 && n != 2 && n != 4 && n != 8))
        throw Error(ErrorKind::Input, entry + ": \"ensemble\" must be 1, 2, 4 or 8 (the flips and transposes "
                                              "averaged), not " + n.dump());
      a.ensemble = n.get<int>();
    }
    if (e.contains("description") && e["description"].is_string()) a.description = e["description"].get<std::string>();
    if (e.contains("validation")) a.validation = e["validation"].dump();
    if (e.contains("benchmark")) a.benchmark = e["benchmark"].dump();
    out.push_back(std::move(a));
  }
  return out;
}

// Every model folder's aliases.json, in model_dirs() order.
std::vector<std::filesystem::path> alias_files() {
  std::vector<std::filesystem::path> out;
  for (const auto& dir : model_dirs()) {
    std::error_code ec;
    if (std::filesystem::is_regular_file(dir / "aliases.json", ec)) out.push_back(dir / "aliases.json");
  }
  return out;
}

}  // namespace

std::vector<ModelAlias> list_model_aliases(std::vector<std::string>* problems) {
  std::vector<ModelAlias> out;
  for (const auto& file : alias_files()) {
    try {
      for (auto& a : read_aliases(file)) {
        const bool seen = std::any_of(out.begin(), out.end(), [&](const ModelAlias& b) { return b.name == a.name; });
        if (!seen) out.push_back(std::move(a));
      }
    } catch (const std::exception& e) {
      if (problems) problems->push_back(e.what());
    }
  }
  return out;
}

std::optional<ModelAlias> find_model_alias(const std::string& name) {
  for (const auto& file : alias_files())
    for (auto& a : read_aliases(file))
      if (a.name == name) return a;
  return std::nullopt;
}

}  // namespace residue::nn
