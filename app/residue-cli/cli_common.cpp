#include "cli_common.h"

#include "app/common/cli_enum.h"

#include <map>

#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/metrics/metrics.h"
#include "core/util/error.h"

namespace residue::cli {

void InputOptions::add_to(CLI::App& app, bool with_reference) {
  app.add_option("inputs", inputs,
                 "The render: one multilayer EXR, a folder (Tungsten, OIDN), or several single-AOV files")
      ->required();
  app.add_option("--map", map_flags,
                 "Map an AOV explicitly: ROLE=[FILE:]CHANNELS, e.g. albedo=diffuse.R,diffuse.G,diffuse.B, "
                 "normal=n.exr:N.X,N.Y,N.Z or depth=z.exr (ROLE: color, albedo, normal, depth, variance, reference)")
      ->type_name("ROLE=SPEC");
  app.add_option("--mapping", mapping_file, "A JSON channel mapping file (see docs/AOVS.md)")
      ->check(CLI::ExistingFile);
  app.add_option("--layer", layer, "The view layer / prefix to use when a file holds several");
  app.add_option("--normal-space", normal_space, "Override the normals' space")
      ->check(CLI::IsMember({"camera", "world", "unknown"}));
  if (with_reference)
    // No CLI11 existence check: a missing reference is bad input (exit 3, from the loader), like a missing render.
    app.add_option("-r,--reference", reference, "The reference (high-spp) image, when not found by convention");
}

LoadOptions InputOptions::load_options() const {
  LoadOptions o;
  if (!mapping_file.empty()) o.mapping = ChannelMapping::from_json_file(mapping_file);
  ChannelMapping flags;
  for (const auto& f : map_flags) flags.add_flag(f);
  o.mapping.merge(flags);
  if (!layer.empty()) o.mapping.layer_prefix = layer;
  if (!reference.empty()) o.reference = reference;
  if (!normal_space.empty()) o.normal_space = normal_space_from_string(normal_space);
  return o;
}

std::vector<std::filesystem::path> InputOptions::files_named() const {
  std::vector<std::filesystem::path> files(inputs.begin(), inputs.end());
  if (!reference.empty()) files.emplace_back(reference);
  if (!mapping_file.empty()) files.emplace_back(mapping_file);
  for (const auto& f : map_flags) {
    ChannelMapping one;
    try {
      one.add_flag(f);
    } catch (const Error&) {
      continue;  // reported when the stack is loaded
    }
    for (const auto& [role, binding] : one.roles)
      if (!binding.file.empty()) files.push_back(binding.file);
  }
  return files;
}

AovStack InputOptions::load() const {
  std::vector<std::filesystem::path> paths(inputs.begin(), inputs.end());
  return load_aov_stack(paths, load_options());
}

CLI::Validator non_empty(const std::string& expected) {
  return CLI::Validator([expected](std::string& value) { return value.empty() ? "is empty: give " + expected : std::string(); },
                        "", "NON_EMPTY");
}

CLI::Validator positive_finite() {
  return CLI::Validator(
      [](std::string& value) {
        double v = 0;
        return CLI::detail::lexical_cast(value, v) && std::isfinite(v) && v > 0 ? std::string()
                                                                               : "must be a finite number above 0, not '" + value + "'";
      },
      "", "POSITIVE");
}

int exit_code_for(ErrorKind kind) {
  switch (kind) {
    case ErrorKind::Input:
    case ErrorKind::Mapping: return kInputError;
    case ErrorKind::Output: return kOutputError;
    case ErrorKind::Usage: return kUsageError;
  }
  return kInternalError;
}

Rect parse_roi(const std::string& text) {
  Rect r;
  char c1 = 0, c2 = 0, c3 = 0;
  std::istringstream in(text);
  if (!(in >> r.x >> c1 >> r.y >> c2 >> r.width >> c3 >> r.height) || c1 != ',' || c2 != ',' || c3 != ',' ||
      !in.eof() || r.width <= 0 || r.height <= 0 || r.x < 0 || r.y < 0)
    throw CLI::ValidationError("--roi", "expected x,y,w,h with w,h > 0 and x,y >= 0; got \"" + text + "\"");
  return r;
}

static std::string format_psnr(double psnr) {
  if (std::isinf(psnr)) return "inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", psnr);
  return buf;
}

void print_metrics_table(const io::MetricsReport& report) {
  std::printf("reference  %s (%lldx%lld)\n", display_path(report.reference_file).c_str(),
              static_cast<long long>(report.width), static_cast<long long>(report.height));
  std::printf("region     %s\n\n",
              report.options.roi ? ("ROI " + report.options.roi->to_string()).c_str() : "whole image");
  std::printf("%-10s %12s %12s %10s %9s %10s %10s%s\n", "image", "relMSE", "MSE", "PSNR dB", "SSIM", "pixels",
              "excluded", report.flip ? "   HDR-FLIP" : "");
  for (const auto& row : report.rows) {
    const auto& s = row.scores;
    char flip[32] = "";
    if (row.hdr_flip) std::snprintf(flip, sizeof flip, " %10.5f", *row.hdr_flip);
    std::printf("%-10s %12.6g %12.6g %10s %9.5f %10lld %10lld%s\n", row.name.c_str(), s.relmse, s.mse,
                format_psnr(s.psnr).c_str(), s.ssim, static_cast<long long>(s.pixels),
                static_cast<long long>(s.excluded_test + s.excluded_reference), flip);
  }
  std::printf("\n%s\n", metrics::formula_text(report.options).c_str());
  if (report.flip) std::printf("\n%s\n", metrics::flip_formula_text(*report.flip).c_str());
}

std::string display_path(const std::string& path) {
  std::error_code ec;
  const auto rel = std::filesystem::relative(path, std::filesystem::current_path(), ec);
  if (!ec && !rel.empty() && rel.string().size() < path.size()) return rel.string();
  return path;
}

CLI::Option* add_on_off(CLI::App* cmd, const std::string& name, bool& value, const std::string& help) {
  return add_enum_option<bool>(cmd, name, value, {{"on", true}, {"off", false}}, help);
}

}  // namespace residue::cli
