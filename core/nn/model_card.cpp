#include "core/nn/model_card.h"

#include <algorithm>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "core/nn/model_alias.h"
#include "core/nn/model_registry.h"
#include "core/nn/oidn_network.h"

namespace residue::nn {

namespace {
std::optional<double> number(const nlohmann::json& j, const char* key) {
  if (j.is_object() && j.contains(key) && j[key].is_number()) return j[key].get<double>();
  return std::nullopt;
}

nlohmann::json json_of(const std::map<std::string, std::string>& meta, const char* key) {
  const auto it = meta.find(key);
  return it == meta.end() ? nlohmann::json() : nlohmann::json::parse(it->second, nullptr, /*allow_exceptions=*/false);
}

std::optional<ModelCard::Validation> validation_of(const nlohmann::json& v) {
  const auto relmse = number(v, "relmse"), ssim = number(v, "ssim");
  if (!relmse || !ssim) return std::nullopt;
  ModelCard::Validation out{*relmse, *ssim, number(v, "noisy_relmse"), 0};
  if (const auto n = number(v, "scenes")) out.scenes = static_cast<int>(*n);
  else if (v.contains("per_scene") && v["per_scene"].is_array()) out.scenes = static_cast<int>(v["per_scene"].size());
  return out;
}

std::optional<ModelCard::Benchmark> benchmark_of(const nlohmann::json& b) {
  if (!b.is_object()) return std::nullopt;
  ModelCard::Benchmark out{number(b, "fp32_s_per_mp"), number(b, "bf16_s_per_mp"), {}};
  if (b.contains("machine") && b["machine"].is_string()) out.machine = b["machine"].get<std::string>();
  if (!out.fp32_s_per_mp && !out.bf16_s_per_mp) return std::nullopt;
  return out;
}

// OIDN's cards, from cards.json beside its networks.
nlohmann::json oidn_cards(const std::filesystem::path& dir) {
  std::ifstream in(dir / "cards.json");
  if (!in) return {};
  return nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
}

double gflop_per_mp(const Model& m) {  // every network a denoise with `m` runs
  double flops = m.graph.flops_per_pixel() * m.ensemble;  // its self-ensemble's members; what runs first, once
  for (const auto& pre : {m.albedo_prefilter, m.normal_prefilter, m.prior})  // networks run before this one
    if (pre) flops += pre->graph.flops_per_pixel();
  return flops * 1e6 / 1e9;
}
}  // namespace

Method method_of(std::string_view family) {
  if (family == "bilateral") return Method::Bilateral;
  if (family == "oidn" || family == "oidn-cleanaux") return Method::Oidn;
  return Method::Residue;
}

const char* to_string(Method m) {
  switch (m) {
    case Method::Residue: return "residue";
    case Method::Oidn: return "oidn";
    case Method::Bilateral: return "bilateral";
  }
  return "?";
}

std::optional<double> ModelCard::seconds_per_mp(Precision p) const {
  if (!benchmark) return std::nullopt;
  return p == Precision::BF16 ? benchmark->bf16_s_per_mp : benchmark->fp32_s_per_mp;
}

ModelCard model_card(const Model& model, const std::string& family) {
  ModelCard c;
  c.family = family;
  c.method = model.method;
  c.file = model.path;
  c.gflop_per_mp = gflop_per_mp(model);
  c.reach_px = model.graph.receptive_reach();
  if (model.method == Method::Oidn) {
    c.architecture = std::string("OIDN ") + oidn_network_name(model.graph);
    c.description = model.oidn.clean_aux ? "Intel Open Image Denoise 2.4, albedo and normal denoised first"
                                         : "Intel Open Image Denoise 2.4 (rt_hdr_alb_nrm; rt_hdr without AOVs)";
    const auto cards = oidn_cards(std::filesystem::path(model.path).parent_path());
    if (cards.is_object() && cards.contains(family)) {
      c.validation = validation_of(cards[family].value("validation", nlohmann::json()));
      c.benchmark = benchmark_of(cards[family].value("benchmark", nlohmann::json()));
    }
    return c;
  }
  c.ensemble = model.ensemble;
  c.architecture = model.network.arch.to_string();
  if (model.ensemble > 1) c.architecture += ", self-ensemble x" + std::to_string(model.ensemble);
  if (const auto it = model.metadata.find("description"); it != model.metadata.end()) c.description = it->second;
  // The file's numbers were measured as the file runs: not for a model told to run as another ensemble (an alias).
  const auto file_ensemble = model.metadata.find("residue.ensemble");
  if (model.ensemble == (file_ensemble == model.metadata.end() ? 1 : std::stoi(file_ensemble->second))) {
    c.validation = validation_of(json_of(model.metadata, "validation"));
    c.benchmark = benchmark_of(json_of(model.metadata, "benchmark"));
  }
  if (const auto it = model.metadata.find("residue.blend_tau"); it != model.metadata.end()) {
    try {
      c.blend_tau = std::stof(it->second);
    } catch (const std::exception&) {
      // an unreadable tau is the denoiser's to report; the card shows none
    }
  }
  return c;
}

std::vector<ModelCard> list_model_cards(std::vector<std::string>* problems) {
  std::map<std::string, ModelCard> families;
  std::map<std::string, std::vector<std::string>> variants;
  for (const auto& dir : model_dirs()) {
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec)) continue;
    for (const auto& file : std::filesystem::directory_iterator(dir, ec)) {
      if (file.path().extension() != ".safetensors") continue;
      std::string family = file.path().stem().string();
      std::string variant = to_string(FeatureSet::Full);
      // The variant suffixes are find_model_for's (model_variant_name).
      for (FeatureSet set : {FeatureSet::ColorAlbedoNormal, FeatureSet::ColorOnly, FeatureSet::FullVariance}) {
        const std::string suffix = model_variant_name("", set);
        if (family.size() > suffix.size() && family.ends_with(suffix)) {
          family.resize(family.size() - suffix.size());
          variant = to_string(set);
        }
      }
      auto& v = variants[family];
      if (std::find(v.begin(), v.end(), variant) == v.end()) v.push_back(variant);
      if (variant != to_string(FeatureSet::Full) || families.count(family)) continue;  // the first folder wins
      try {
        families[family] = model_card(load_model(file.path()), family);
      } catch (const std::exception& e) {
        if (problems) problems->push_back(e.what());
      }
    }
  }
  std::vector<ModelCard> out;
  ModelCard bilateral;
  bilateral.family = "bilateral";
  bilateral.method = Method::Bilateral;
  bilateral.architecture = "cross-bilateral filter";
  bilateral.description = "cross-bilateral filter guided by albedo, normal and depth";
  out.push_back(bilateral);
  std::vector<ModelCard> nets;
  for (auto& [name, card] : families) {
    card.variants = variants[name];
    nets.push_back(card);
  }
  for (const auto& alias : list_model_aliases(problems)) {
    try {
      ModelCard card = model_card(load_model_for(alias.name, FeatureSet::Full), alias.name);
      card.alias_of = alias.model;
      card.variants = variants[alias.model];
      if (!alias.description.empty()) card.description = alias.description;
      if (auto v = validation_of(nlohmann::json::parse(alias.validation, nullptr, false)); v) card.validation = v;
      if (auto b = benchmark_of(nlohmann::json::parse(alias.benchmark, nullptr, false)); b) card.benchmark = b;
      nets.push_back(card);
    } catch (const std::exception& e) {
      if (problems) problems->push_back(alias.file.string() + ": alias \"" + alias.name + "\": " + e.what());
    }
  }
  std::sort(nets.begin(), nets.end(), [](const ModelCard& a, const ModelCard& b) { return a.gflop_per_mp < b.gflop_per_mp; });
  out.insert(out.end(), nets.begin(), nets.end());
  // Intel's networks, for comparison: picked by core as for the CLI (rt_hdr_alb_nrm, or rt_hdr without AOVs).
  for (const char* family : {"oidn", "oidn-cleanaux"}) {
    try {
      out.push_back(model_card(load_model(find_model_for(family, FeatureSet::Full)), family));
    } catch (const std::exception& e) {
      if (problems) problems->push_back(e.what());
    }
  }
  return out;
}

}  // namespace residue::nn
