// residue-cli models: the model cards (core/nn/model_card.h) of every denoiser a -m name selects, as a table or
// JSON: what each costs, how fast it was measured and on what, how accurate on the validation scenes. The
// viewer's model table shows the same cards.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "cli_common.h"
#include "commands.h"
#include "core/nn/model_card.h"

namespace residue::cli {
namespace {

nlohmann::json to_json(const nn::ModelCard& c) {
  nlohmann::json j = {{"family", c.family},        {"method", nn::to_string(c.method)},
                      {"file", c.file.string()},   {"architecture", c.architecture},
                      {"gflop_per_mp", c.gflop_per_mp}, {"variants", c.variants},
                      {"description", c.description}};
  if (c.validation)
    j["validation"] = {{"relmse", c.validation->relmse}, {"ssim", c.validation->ssim}, {"scenes", c.validation->scenes},
                       {"noisy_relmse", c.validation->noisy_relmse ? nlohmann::json(*c.validation->noisy_relmse) : nlohmann::json()}};
  if (c.benchmark) {
    const auto opt = [](const std::optional<double>& v) { return v ? nlohmann::json(*v) : nlohmann::json(); };
    j["benchmark"] = {{"fp32_s_per_mp", opt(c.benchmark->fp32_s_per_mp)},
                      {"bf16_s_per_mp", opt(c.benchmark->bf16_s_per_mp)},
                      {"machine", c.benchmark->machine}};
  }
  if (c.method != nn::Method::Bilateral) j["reach_px"] = c.reach_px;  // a network's; the filter's is its radius
  if (c.blend_tau) j["blend_tau"] = *c.blend_tau;
  if (!c.alias_of.empty()) j["alias_of"] = c.alias_of;
  return j;
}

std::string cell(const std::optional<double>& v, const char* format) {
  if (!v) return "-";
  char buf[32];
  std::snprintf(buf, sizeof buf, format, *v);
  return buf;
}

void print_table(const std::vector<nn::ModelCard>& cards) {
  const auto name_of = [](const nn::ModelCard& c) {
    return c.alias_of.empty() ? c.family : c.family + " = " + c.alias_of;
  };
  // The two text columns are as wide as their longest entry: an alias's name and a multi-scale architecture are
  // long, and a cut-off architecture would hide the self-ensemble an alias runs.
  int name_w = 5, arch_w = 12;
  for (const auto& c : cards) {
    name_w = std::max(name_w, static_cast<int>(name_of(c).size()));
    arch_w = std::max(arch_w, static_cast<int>(c.architecture.size()));
  }
  std::printf("%-*s %-10s %-*s %9s %9s %9s %9s %7s %6s\n", name_w, "model", "method", arch_w, "architecture",
              "GFLOP/MP", "s/MP fp32", "s/MP bf16", "relMSE", "SSIM", "scenes");
  for (const auto& c : cards) {
    const bool net = c.method != nn::Method::Bilateral;
    std::printf("%-*s %-10s %-*s %9s %9s %9s %9s %7s %6s\n", name_w, name_of(c).c_str(), nn::to_string(c.method),
                arch_w, c.architecture.c_str(), net ? cell(c.gflop_per_mp, "%.0f").c_str() : "-",
                cell(c.seconds_per_mp(nn::Precision::FP32), "%.3g").c_str(),
                cell(c.seconds_per_mp(nn::Precision::BF16), "%.3g").c_str(),
                cell(c.validation ? std::optional<double>(c.validation->relmse) : std::nullopt, "%.3g").c_str(),
                cell(c.validation ? std::optional<double>(c.validation->ssim) : std::nullopt, "%.4f").c_str(),
                cell(c.validation && c.validation->scenes > 0 ? std::optional<double>(c.validation->scenes) : std::nullopt,
                     "%.0f").c_str());
  }
  std::printf("\ns/MP: seconds per megapixel as benchmarked (machine per model: --json); relMSE, SSIM: means over "
              "that many validation scenes. NAME = MODEL: an alias, MODEL run as the architecture says.\n");
}

}  // namespace

Command add_models_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("models", "List the models -m can pick, with their cost, speed and validation scores");
  auto json = std::make_shared<bool>(false);
  cmd->add_flag("--json", *json, "Print JSON instead of a table");
  return {cmd, [=]() {
    std::vector<std::string> problems;
    const auto cards = nn::list_model_cards(&problems);
    for (const auto& p : problems) std::fprintf(stderr, "note: %s\n", p.c_str());
    if (*json) {
      nlohmann::json j = nlohmann::json::array();
      for (const auto& c : cards) j.push_back(to_json(c));
      std::cout << j.dump(2) << "\n";
    } else {
      print_table(cards);
    }
    return static_cast<int>(kOk);
  }};
}

}  // namespace residue::cli
