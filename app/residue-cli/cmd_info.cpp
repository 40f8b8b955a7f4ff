// residue-cli info: what a render holds and how its channels were mapped to AOVs.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "cli_common.h"
#include "commands.h"

namespace residue::cli {
namespace {

std::string join(const std::vector<std::string>& v, const char* sep = ",") {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) s += (i ? sep : "") + v[i];
  return s;
}

std::string describe(AovRole role, const AovStack& stack) {
  switch (role) {
    case AovRole::Normal: return std::string(to_string(stack.normal_space)) + " space";
    case AovRole::Depth:
      return std::string(to_string(stack.depth_kind)) + ", " + std::to_string(stack.depth_background_pixels) +
             " background px";
    default: return "";
  }
}

nlohmann::json to_json(const AovStack& stack) {
  nlohmann::json j;
  j["convention"] = stack.convention;
  j["width"] = stack.width();
  j["height"] = stack.height();
  j["data_window"] = {stack.data_window.x, stack.data_window.y, stack.data_window.width, stack.data_window.height};
  j["display_window"] = {stack.display_width, stack.display_height};
  j["normal_space"] = to_string(stack.normal_space);
  j["camera_known"] = stack.world_to_camera.has_value();
  j["depth_background_pixels"] = stack.depth_background_pixels;
  j["notes"] = stack.notes;
  for (AovRole role : kAllAovRoles) {
    const Aov* aov = stack.find(role);
    if (!aov) {
      j["aovs"][to_string(role)] = nullptr;
      continue;
    }
    j["aovs"][to_string(role)] = {{"file", aov->source.file},
                                  {"subimage", aov->source.subimage},
                                  {"layer", aov->source.layer},
                                  {"channels", aov->source.channels},
                                  {"pixel_types", aov->source.pixel_types},
                                  {"nan", aov->non_finite.nan},
                                  {"inf", aov->non_finite.inf},
                                  {"uncovered_pixels", aov->uncovered_pixels}};
  }
  return j;
}

// "half,half,half" -> "half"; mixed types stay listed.
std::string types_text(const std::vector<std::string>& types) {
  for (const auto& t : types)
    if (t != types.front()) return join(types);
  return types.empty() ? "" : types.front();
}

// The component part of each channel name: "ViewLayer.Combined.R" -> "R".
std::string components_text(const std::vector<std::string>& channels) {
  std::vector<std::string> comps;
  for (const auto& c : channels) {
    const auto dot = c.rfind('.');
    comps.push_back(dot == std::string::npos || dot + 1 == c.size() ? c : c.substr(dot + 1));
  }
  return join(comps);
}

void print_table(const AovStack& stack, bool list_channels_too, const std::vector<std::string>& inputs) {
  std::printf("convention  %s\n", stack.convention.c_str());
  std::printf("size        %lld x %lld", static_cast<long long>(stack.width()), static_cast<long long>(stack.height()));
  if (stack.data_window != Rect{0, 0, stack.display_width, stack.display_height})
    std::printf("  (data window %s of display %lldx%lld)", stack.data_window.to_string().c_str(),
                static_cast<long long>(stack.display_width), static_cast<long long>(stack.display_height));
  std::printf("\ncamera      %s\n", stack.world_to_camera ? "known (world to camera from the header)" : "not in the file");
  // Files get a number each, so the table stays narrow.
  std::vector<std::string> files;
  for (AovRole role : kAllAovRoles)
    if (const Aov* aov = stack.find(role))
      if (std::find(files.begin(), files.end(), aov->source.file) == files.end()) files.push_back(aov->source.file);
  for (size_t i = 0; i < files.size(); ++i)
    std::printf("%-11s [%zu] %s\n", i == 0 ? "files" : "", i + 1, display_path(files[i]).c_str());

  std::printf("\n%-10s %-4s %-30s %-8s %-6s %8s %8s  %s\n", "AOV", "file", "layer", "channels", "stored", "NaN",
              "Inf", "notes");
  for (AovRole role : kAllAovRoles) {
    const Aov* aov = stack.find(role);
    if (!aov) {
      std::printf("%-10s %s\n", to_string(role), "-");
      continue;
    }
    const size_t file_no = static_cast<size_t>(std::find(files.begin(), files.end(), aov->source.file) - files.begin()) + 1;
    std::printf("%-10s [%zu]  %-30s %-8s %-6s %8lld %8lld  %s\n", to_string(role), file_no, aov->source.layer.c_str(),
                components_text(aov->source.channels).c_str(), types_text(aov->source.pixel_types).c_str(),
                static_cast<long long>(aov->non_finite.nan), static_cast<long long>(aov->non_finite.inf),
                describe(role, stack).c_str());
  }
  if (!stack.notes.empty()) {
    std::printf("\nnotes\n");
    for (const auto& n : stack.notes) std::printf("  - %s\n", n.c_str());
  }
  if (list_channels_too) {
    for (const auto& in : inputs) {
      std::error_code ec;
      if (std::filesystem::is_directory(in, ec)) continue;
      FileChannels fc = list_channels(in);
      std::printf("\nchannels of %s (%lldx%lld)\n", display_path(fc.file).c_str(), static_cast<long long>(fc.width),
                  static_cast<long long>(fc.height));
      for (const auto& c : fc.channels)
        std::printf("  [part %d] %-40s %s\n", c.subimage, c.name.c_str(), c.pixel_type.c_str());
    }
  }
}

}  // namespace

Command add_info_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("info", "Show what a render holds and how its channels map to AOVs");
  auto opts = std::make_shared<InputOptions>();
  auto json = std::make_shared<bool>(false);
  auto channels = std::make_shared<bool>(false);
  opts->add_to(*cmd, true);
  cmd->add_flag("--json", *json, "Print JSON instead of a table");
  cmd->add_flag("--channels", *channels, "Also list every channel of every input file");
  return {cmd, [=]() {
    const AovStack stack = opts->load();
    if (*json) std::cout << to_json(stack).dump(2) << "\n";
    else print_table(stack, *channels, opts->inputs);
    return static_cast<int>(kOk);
  }};
}

}  // namespace residue::cli
