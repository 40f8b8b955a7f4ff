#include "core/aov/conventions.h"

#include <algorithm>
#include <regex>

namespace residue {
namespace fs = std::filesystem;
namespace {

// --- file sets -------------------------------------------------------------------------------------------------

// OIDN's training data: NAME_0016spp.hdr.exr beside NAME_0016spp.{alb,nrm,z}.exr and NAME_ref.hdr.exr.
class OidnDataSet final : public FileSetConvention {
 public:
  std::string name() const override { return "OIDN data set"; }
  std::string colour_file_pattern() const override { return "NAME_NNNNspp.hdr.exr (OIDN data set)"; }
  std::vector<fs::path> colour_files_in(const fs::path& folder) const override {
    std::vector<fs::path> found;
    for (const auto& entry : fs::directory_iterator(folder))
      if (claims(entry.path())) found.push_back(entry.path());
    std::sort(found.begin(), found.end());
    return found;
  }
  bool claims(const fs::path& colour_file) const override {
    return std::regex_match(colour_file.filename().string(), pattern());
  }
  std::map<AovRole, fs::path> siblings(const fs::path& colour_file) const override {
    std::smatch m;
    const std::string file = colour_file.filename().string();
    if (!std::regex_match(file, m, pattern())) return {};
    const fs::path dir = colour_file.parent_path();
    const std::string base = m[1].str() + "_" + m[2].str();
    return {{AovRole::Albedo, dir / (base + ".alb.exr")},
            {AovRole::Normal, dir / (base + ".nrm.exr")},
            {AovRole::Depth, dir / (base + ".z.exr")},
            {AovRole::Reference, dir / (m[1].str() + "_ref.hdr.exr")}};
  }

 private:
  static const std::regex& pattern() {
    static const std::regex re(R"(^(.*)_(\d+spp)\.hdr\.exr$)", std::regex::icase);
    return re;
  }
};

// Tungsten: fixed names in the render's folder; normals in world space, depth as the primary ray's length.
class Tungsten final : public FileSetConvention {
 public:
  std::string name() const override { return "Tungsten file set"; }
  std::string colour_file_pattern() const override { return "color.exr (Tungsten)"; }
  std::vector<fs::path> colour_files_in(const fs::path& folder) const override {
    if (fs::exists(folder / "color.exr")) return {folder / "color.exr"};
    return {};
  }
  bool claims(const fs::path&) const override { return true; }  // the fallback for any single-layer file
  std::map<AovRole, fs::path> siblings(const fs::path& colour_file) const override {
    const fs::path dir = colour_file.parent_path();
    const std::string stem = colour_file.stem().string();
    std::map<AovRole, fs::path> s = {{AovRole::Albedo, dir / "albedo.exr"},
                                     {AovRole::Normal, dir / "normal.exr"},
                                     {AovRole::Depth, dir / "depth.exr"},
                                     {AovRole::Variance, dir / (stem + "Variance.exr")}};
    if (stem != "reference") s[AovRole::Reference] = dir / "reference.exr";
    return s;
  }
  NormalSpace normal_space() const override { return NormalSpace::World; }
  DepthKind depth_kind() const override { return DepthKind::RayLength; }
};

}  // namespace

const std::vector<std::unique_ptr<const FileSetConvention>>& file_set_conventions() {
  static const auto list = [] {
    std::vector<std::unique_ptr<const FileSetConvention>> l;
    l.push_back(std::make_unique<OidnDataSet>());
    l.push_back(std::make_unique<Tungsten>());
    return l;
  }();
  return list;
}

std::optional<fs::path> reference_beside(const fs::path& render) {
  const fs::path ref = render.parent_path() / "reference.exr";
  std::error_code ec;
  if (!fs::is_regular_file(ref, ec) || fs::equivalent(ref, render, ec)) return std::nullopt;
  return ref;
}

// --- layered files -----------------------------------------------------------------------------------------------

const std::vector<LayeredConvention>& layered_conventions() {
  // Spelled out: in nested braces, strings can be taken for the (first, last) iterators of a vector constructor.
  using Layers = std::vector<std::string>;
  static const std::vector<LayeredConvention> list = {
      {"Blender Cycles",
       {Layers{"combined"}, Layers{"noisy image"}, Layers{"denoising albedo"}, Layers{"denoising normal"},
        Layers{"denoising depth"}},
       false,
       {
           {AovRole::Color, {"noisy image", "combined"}},
           {AovRole::Albedo, {"denoising albedo"}},
           {AovRole::Albedo, {"diffcol"}, {}, "albedo taken from DiffCol (no Denoising Albedo pass)"},
           {AovRole::Normal, {"denoising normal"}, {.normal_space = NormalSpace::Camera, .flip_normal_z = true}},
           {AovRole::Normal, {"normal"}, {.normal_space = NormalSpace::World}},
           {AovRole::Depth, {"denoising depth"}, {.depth_kind = DepthKind::RayLength}},
           {AovRole::Depth, {"depth"}, {.depth_kind = DepthKind::Planar}},
           {AovRole::Variance, {"denoising variance"}},
           {AovRole::Reference, {"reference"}},
           {AovRole::Motion, {"vector"}, {.cycles_vector = true}},
       }},
      {"RenderMan",
       {Layers{"ci"}},
       false,
       {
           {AovRole::Color, {"ci"}},
           {AovRole::Albedo, {"albedo"}},
           {AovRole::Normal, {"normal"}, {},
            "RenderMan normal: space not stated in the file (give --normal-space)"},
           {AovRole::Depth, {"zfiltered", "z"}, {.depth_kind = DepthKind::Planar}},
           {AovRole::Variance, {"mse"}},
           {AovRole::Reference, {"reference"}},
       }},
      {"V-Ray",
       {Layers{"bump_normals"}, Layers{"bumpnormals"}, Layers{"diffuse"}},
       true,
       {
           {AovRole::Color, {"", "rgb", "rgba"}},
           {AovRole::Albedo, {"diffuse"}},
           {AovRole::Normal, {"bump_normals", "bumpnormals", "normals"}, {.normal_space = NormalSpace::Camera}},
           {AovRole::Depth, {"zdepth", "vrayzdepth", "z"}, {},
            "V-Ray depth is often normalised (zdepth min/max); treated as relative depth"},
           {AovRole::Variance, {"variance"}},
           {AovRole::Reference, {"reference"}},
       }},
      // pbrt-v4's gbuffer film. Before Arnold, whose signature ("N" with "Z") it may also carry. Its Variance is the samples'
      // variance (the estimate's times the spp): divided by the samplesPerPixel pbrt writes in the header.
      {"pbrt-v4 (gbuffer film)",
       {Layers{"albedo", "p", "ns"}},
       true,
       {
           {AovRole::Color, {""}},
           {AovRole::Albedo, {"albedo"}},
           {AovRole::Normal, {"ns"}, {.normal_space = NormalSpace::Camera, .flip_normal_z = true},
            "pbrt-v4 gbuffer: positions and normals are in camera space unless the film's \"coordinatesystem\" was "
            "\"world\" (then give --normal-space world)"},
           {AovRole::Depth, {"p"}, {.depth_kind = DepthKind::Planar, .depth_from_position = true}},
           {AovRole::Variance, {"variance"}, {.samples_variance = true}},
           {AovRole::Reference, {"reference"}},
       }},
      {"Arnold",
       {Layers{"denoise_albedo"}, Layers{"diffuse_albedo"}, Layers{"n", "z"}},
       true,
       {
           {AovRole::Color, {"", "rgba", "rgb", "beauty"}},
           {AovRole::Albedo, {"denoise_albedo", "albedo", "diffuse_albedo"}},
           {AovRole::Normal, {"n"}, {.normal_space = NormalSpace::World}},
           {AovRole::Depth, {"z"}, {.depth_kind = DepthKind::Planar}},
           {AovRole::Variance, {"variance", "rgba_variance"}},
           {AovRole::Reference, {"reference"}},
       }},
      {"plain R,G,B with named layers",
       {},
       true,
       {
           {AovRole::Color, {"", "rgba", "rgb", "beauty", "color", "colour"}},
           {AovRole::Albedo, {"albedo"}},
           // "sh_normal", "nn", "dd": the names Mitsuba 3's aov integrator is usually given (the user picks them).
           {AovRole::Normal, {"normal", "normals", "n", "sh_normal", "nn"}},
           {AovRole::Depth, {"depth", "z", "dd"}},
           {AovRole::Variance, {"variance", "colorvariance"}},
           {AovRole::Reference, {"reference", "ref"}},
       }},
  };
  return list;
}

}  // namespace residue
