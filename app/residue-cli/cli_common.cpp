#include "cli_common.h"

#include <sstream>

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
    app.add_option("-r,--reference", reference, "The reference (high-spp) image, when not found by convention")
        ->check(CLI::ExistingFile);
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

AovStack InputOptions::load() const {
  std::vector<std::filesystem::path> paths(inputs.begin(), inputs.end());
  return load_aov_stack(paths, load_options());
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

std::string display_path(const std::string& path) {
  std::error_code ec;
  const auto rel = std::filesystem::relative(path, std::filesystem::current_path(), ec);
  if (!ec && !rel.empty() && rel.string().size() < path.size()) return rel.string();
  return path;
}

}  // namespace residue::cli
