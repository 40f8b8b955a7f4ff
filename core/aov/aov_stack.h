// AovStack: everything a denoise needs from a render, and nothing more.
//
// Beauty colour (required), and optionally albedo, normal, depth, per-pixel variance and a reference colour,
// each with the file and channels it came from. All AOVs share one pixel grid: the data window of the colour
// source. Values are linear floats as stored, with these normalisations done by the loader:
//  - normal: when `normal_space` is Camera, x right, y up, +z towards the viewer (OpenGL view space);
//    Cycles' "Denoising Normal" (+z along the view direction) is flipped to that. World-space normals are kept
//    as they are, with the camera (when known) in `world_to_camera`.
//  - depth: distance from the camera, >= 0; background pixels are 0 whatever sentinel the renderer used
//    (Cycles Depth.Z 1e10, +Inf, any value >= 1e9), counted in depth_background_pixels.
//  - NaN/Inf values are kept, counted per AOV, and reported; consumers sanitise.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <OpenImageIO/paramlist.h>

#include "core/image/image.h"

namespace residue {

// Motion: per pixel, where its surface was in the previous frame and will be in the next (core/temporal/
// reprojection.h has the convention: 4 channels, pixels, y down the rows), for temporal denoising.
enum class AovRole { Color, Albedo, Normal, Depth, Variance, Reference, Motion };
inline constexpr std::array<AovRole, 7> kAllAovRoles{AovRole::Color,    AovRole::Albedo,    AovRole::Normal,
                                                     AovRole::Depth,    AovRole::Variance,  AovRole::Reference,
                                                     AovRole::Motion};
const char* to_string(AovRole role);  // "color", "albedo", ...
std::optional<AovRole> aov_role_from_string(const std::string& name);
// Channels an AOV of this role holds in the stack (variance: 3, or 1 when the renderer stores one; motion 4).
int expected_channels(AovRole role);

enum class NormalSpace { Camera, World, Unknown };
const char* to_string(NormalSpace space);
std::optional<NormalSpace> normal_space_from_string(const std::string& name);

enum class DepthKind { Planar, RayLength, Unknown };
const char* to_string(DepthKind kind);

// Where one AOV came from.
struct AovSource {
  std::string file;
  int subimage = 0;
  std::string layer;                      // the pass/layer name it was recognised by, e.g. "Denoising Albedo"
  std::vector<std::string> channels;      // channel names as stored in the file
  std::vector<std::string> pixel_types;   // as stored: "half", "float", "uint"
};

struct Aov {
  Image image;
  AovSource source;
  NonFiniteCount non_finite;
  int64_t uncovered_pixels = 0;  // grid pixels outside this AOV's data window (filled with 0)
};

// A neighbouring frame of a shot seen from this frame (core/temporal/frame_window.h): its noisy colour warped
// along the motion, and where that is the same surface. A temporal model reads these (set by the caller, never
// loaded with the frame).
struct WarpedNeighbour {
  int offset = 0;  // -1 the previous frame, +1 the next, -2 ...
  Image color;     // 3 channels on this frame's grid; this frame's own colour where not valid
  Image valid;     // 1 channel: 1 where the neighbour shows the same surface, 0 where masked or missing
};

// The offsets of the neighbours a temporal model of radius k reads, in its planes' order: -k..-1, +1..+k.
std::vector<int> neighbour_offsets(int radius);

struct AovStack {
  std::string convention;  // how the inputs were recognised: "Blender Cycles", "Tungsten file set", ...
  Aov color;
  std::optional<Aov> albedo, normal, depth, variance, reference, motion;
  // Another model's denoised colour, which a post-correction model refines (set by the denoiser, never loaded).
  std::optional<Aov> prior;
  // The neighbouring frames a temporal model reads, by offset (set by the caller, never loaded).
  std::vector<WarpedNeighbour> neighbours;
  const WarpedNeighbour* neighbour(int offset) const;

  NormalSpace normal_space = NormalSpace::Unknown;
  DepthKind depth_kind = DepthKind::Unknown;
  int64_t depth_background_pixels = 0;

  Rect data_window;            // the grid, in display-window coordinates (x, y may be non-zero or negative)
  int64_t display_width = 0;   // the colour source's display window
  int64_t display_height = 0;
  OIIO::ParamValueList metadata;  // the colour source's header attributes
  // World -> camera (row-major, column vectors, camera looks down -z, +y up), when the input says.
  std::optional<std::array<double, 16>> world_to_camera;
  std::vector<std::string> notes;  // assumptions and fallbacks, for `info` and the viewer

  int64_t width() const { return color.image.width(); }
  int64_t height() const { return color.image.height(); }
  // The AOV of a role, or null when the stack has none: the one place that maps roles to the members above.
  const Aov* find(AovRole role) const;
  Aov* find(AovRole role);
  // The AOV of a role, created (empty) when absent.
  Aov& emplace(AovRole role);
  // Floats per pixel of every AOV present (from the channel lists, so a layout without pixels answers too).
  int64_t channel_count() const;
};

}  // namespace residue
