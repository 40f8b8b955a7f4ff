#include "ui/model_catalog.h"

#include <QStringList>

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>

#include "core/nn/model_file.h"
#include "core/nn/network.h"
#include "core/nn/oidn_network.h"
#include "core/nn/safetensors.h"

namespace residue::ui {

namespace {
std::optional<double> number(const nlohmann::json& j, const char* key) {
  if (j.is_object() && j.contains(key) && j[key].is_number()) return j[key].get<double>();
  return std::nullopt;
}

nlohmann::json parse(const std::map<std::string, std::string>& meta, const char* key) {
  const auto it = meta.find(key);
  if (it == meta.end()) return {};
  return nlohmann::json::parse(it->second, nullptr, /*allow_exceptions=*/false);
}

}  // namespace

std::vector<ModelEntry> scan_models(QStringList* problems) {
  const std::vector<std::filesystem::path> dirs = nn::model_dirs();

  std::map<QString, ModelEntry> families;
  std::map<QString, QStringList> variants;
  for (const auto& dir : dirs) {
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec)) continue;
    for (const auto& file : std::filesystem::directory_iterator(dir, ec)) {
      if (file.path().extension() != ".safetensors") continue;
      QString stem = QString::fromStdString(file.path().stem().string());
      QString family = stem;
      QString variant = "full";
      // The variant suffixes are core's (model_variant_name): NAME-albedo-normal, NAME-color, NAME-variance.
      for (FeatureSet set : {FeatureSet::ColorAlbedoNormal, FeatureSet::ColorOnly, FeatureSet::FullVariance}) {
        const QString suffix = QString::fromStdString(nn::model_variant_name("", set));
        if (stem.endsWith(suffix)) {
          family = stem.chopped(suffix.size());
          variant = QString::fromLatin1(to_string(set));
        }
      }
      if (!variants[family].contains(variant)) variants[family] << variant;
      if (variant != "full" || families.count(family)) continue;  // the first folder wins, as in find_model
      try {
        const auto st = nn::read_safetensors(file.path());
        ModelEntry e;
        e.name = family;
        e.path = QString::fromStdString(file.path().string());
        const auto get = [&](const char* k) {
          const auto it = st.metadata.find(k);
          return it == st.metadata.end() ? std::string() : it->second;
        };
        e.blocks = std::atoi(get("residue.blocks").c_str());
        e.width = std::atoi(get("residue.width").c_str());
        e.architecture = QString("%1/%2").arg(e.blocks).arg(e.width);
        nn::Architecture arch;
        arch.blocks = e.blocks;
        arch.width = e.width;
        e.gflop_per_mp = arch.flops_per_pixel() * 1e6 / 1e9;
        const auto val = parse(st.metadata, "validation");
        e.val_relmse = number(val, "relmse");
        e.val_ssim = number(val, "ssim");
        e.noisy_relmse = number(val, "noisy_relmse");
        const auto bench = parse(st.metadata, "benchmark");
        e.s_per_mp_fp32 = number(bench, "fp32_s_per_mp");
        e.s_per_mp_bf16 = number(bench, "bf16_s_per_mp");
        if (bench.is_object() && bench.contains("machine") && bench["machine"].is_string())
          e.benchmark_machine = QString::fromStdString(bench["machine"].get<std::string>());
        families[family] = e;
      } catch (const std::exception& ex) {
        if (problems) *problems << QString::fromStdString(ex.what());
      }
    }
  }
  std::vector<ModelEntry> out;
  ModelEntry bilateral;
  bilateral.name = "bilateral";
  bilateral.variants = "cross-bilateral filter guided by albedo, normal and depth";
  out.push_back(bilateral);
  std::vector<ModelEntry> nets;
  for (auto& [name, e] : families) {
    e.variants = variants[name].join(", ");
    nets.push_back(e);
  }
  std::sort(nets.begin(), nets.end(), [](const ModelEntry& a, const ModelEntry& b) { return a.gflop_per_mp < b.gflop_per_mp; });
  out.insert(out.end(), nets.begin(), nets.end());
  // Intel's networks, for comparison: picked by core as for the CLI (rt_hdr_alb_nrm, or rt_hdr without AOVs).
  for (const char* family : {"oidn", "oidn-cleanaux"}) {
    try {
      const auto path = nn::find_model_for(family, FeatureSet::Full);
      const nn::Model m = nn::load_model(path);
      ModelEntry e;
      e.name = family;
      e.path = QString::fromStdString(path.string());
      e.architecture = QString("OIDN ") + nn::oidn_network_name(m.graph);
      e.gflop_per_mp = m.graph.flops_per_pixel() * 1e6 / 1e9;
      for (const auto& pre : {m.albedo_prefilter, m.normal_prefilter})
        if (pre) e.gflop_per_mp += pre->graph.flops_per_pixel() * 1e6 / 1e9;
      e.variants = m.oidn.clean_aux ? "Intel Open Image Denoise 2.4, albedo and normal denoised first"
                                    : "Intel Open Image Denoise 2.4 (rt_hdr_alb_nrm; rt_hdr without AOVs)";
      out.push_back(e);
    } catch (const std::exception& ex) {
      if (problems) *problems << QString::fromStdString(ex.what());
    }
  }
  return out;
}

}  // namespace residue::ui
