// Renderer conventions, in one registry: how each renderer names its AOVs inside one file, or which files hold
// them when it writes one file per AOV, and what its normals and depth mean. Supporting another renderer is one
// entry here; channel_naming.cpp and file_sets.cpp hold the matching mechanics and never name a renderer.
//
// Layered files (tried in this order; the first whose signature matches wins):
//   Blender Cycles  `ViewLayer.Combined.R`, `ViewLayer.Denoising Albedo.R`, `... Denoising Normal.X`,
//                   `... Denoising Depth.Z` (also `Noisy Image`, `Normal`, `Depth`, `DiffCol`, `Denoising Variance`)
//   RenderMan       `Ci`, `albedo`, `normal`, `zfiltered` / `z`, `mse`
//   V-Ray           root `R,G,B` (channel names may start with "."), `diffuse.{red,green,blue}`, `bump_normals`
//   pbrt-v4         its gbuffer film: root `R,G,B`, `Albedo`, `P`, `N`, `Ns` (camera space by default), `Variance`
//                   (the samples' variance, not the estimate's: not used)
//   Arnold          root `R,G,B(,A)`, `N`, `Z`, `denoise_albedo` / `albedo` (known by `denoise_albedo`,
//                   `diffuse_albedo`, or `N` with `Z`: `N` alone is a common name, not Arnold's mark)
//   plain           root `R,G,B` with layers `albedo`, `normal`, `depth` (`variance`, `reference`)
// File sets (one file per AOV):
//   OIDN data set   NAME_0016spp.hdr.exr, NAME_0016spp.alb.exr, .nrm.exr, .z.exr; reference NAME_ref.hdr.exr
//   Tungsten        color.exr, albedo.exr, normal.exr (world space), depth.exr (path length), colorVariance.exr,
//                   reference.exr; also the fallback for any single-layer colour file
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/aov/aov_stack.h"
#include "core/aov/pass_meaning.h"

namespace residue {

// Where one AOV lives in a layered file: the layer names to try, in order, and what the values mean.
struct PassRule {
  AovRole role = AovRole::Color;
  std::vector<std::string> layers;  // lower case, in order of preference; "" = the root layer
  PassMeaning meaning;
  std::string note;                 // said when this rule is used
};

// A renderer that writes its AOVs as named layers of one file.
struct LayeredConvention {
  std::string name;
  // What identifies the renderer: sets of layer names (lower case); the file must hold every layer of at least
  // one set. None = any file (with root R,G,B when needs_root_rgb).
  std::vector<std::vector<std::string>> signatures;
  bool needs_root_rgb = false;         // the signature also needs root R,G,B
  std::vector<PassRule> rules;         // several rules for one role = fallbacks, in order
};

// The layered conventions, in the order they are tried.
const std::vector<LayeredConvention>& layered_conventions();

// A renderer that writes one file per AOV.
class FileSetConvention {
 public:
  virtual ~FileSetConvention() = default;
  virtual std::string name() const = 0;
  // What its colour file is called, for messages ("color.exr").
  virtual std::string colour_file_pattern() const = 0;
  // Its colour files in `folder` (usually none or one).
  virtual std::vector<std::filesystem::path> colour_files_in(const std::filesystem::path& folder) const = 0;
  // Whether `colour_file` is named as this renderer names colour.
  virtual bool claims(const std::filesystem::path& colour_file) const = 0;
  // Where the other AOVs of `colour_file` would be (the files need not exist).
  virtual std::map<AovRole, std::filesystem::path> siblings(const std::filesystem::path& colour_file) const = 0;
  // What its normal and depth files hold.
  virtual NormalSpace normal_space() const { return NormalSpace::Unknown; }
  virtual DepthKind depth_kind() const { return DepthKind::Unknown; }
};

// The file-set conventions, in the order they claim a colour file; the last claims every file.
const std::vector<std::unique_ptr<const FileSetConvention>>& file_set_conventions();

// A reference beside a layered render, by the name data sets give it (Residue's and the Cycles starter set's
// noisy_a.exr / reference.exr): `reference.exr` in the render's folder, when it exists and is not the render.
std::optional<std::filesystem::path> reference_beside(const std::filesystem::path& render);

}  // namespace residue
