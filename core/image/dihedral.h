// The eight symmetries of the pixel grid (flips and transposes), in one place: the trainer's augmentation and
// the self-ensemble (denoiser.h, DenoiseOptions::ensemble) both use them.
//
// A Dihedral maps a source image to an output image: output pixel (u, v) reads source pixel source(u, v), found
// by swapping u and v when `transpose`, then mirroring x when `flip_x` and y when `flip_y` (in the source's
// width and height). A transposing element swaps the image's width and height.
#pragma once

#include <cstdint>
#include <utility>

#include "core/image/image.h"

namespace residue {

struct Dihedral {
  bool flip_x = false;
  bool flip_y = false;
  bool transpose = false;

  // Element i of the group, i in [0, 8): bit 0 flip_x, bit 1 flip_y, bit 2 transpose (the trainer's numbering).
  // So the first 1, 2, 4 or 8 are the self-ensemble's: identity; mirror x; mirror y; both (a half turn); then
  // the transposing ones. The first four keep a tile's shape.
  static Dihedral from_index(int i) { return {(i & 1) != 0, (i & 2) != 0, (i & 4) != 0}; }
  friend bool operator==(const Dihedral&, const Dihedral&) = default;

  // The element that maps the output back to the source.
  Dihedral inverse() const { return transpose ? Dihedral{flip_y, flip_x, true} : *this; }

  // The output's size for a source of w x h.
  std::pair<int64_t, int64_t> size(int64_t w, int64_t h) const { return transpose ? std::pair{h, w} : std::pair{w, h}; }

  // The source pixel output pixel (u, v) reads, for a source of w x h.
  std::pair<int64_t, int64_t> source(int64_t u, int64_t v, int64_t w, int64_t h) const {
    int64_t x = transpose ? v : u, y = transpose ? u : v;
    if (flip_x) x = w - 1 - x;
    if (flip_y) y = h - 1 - y;
    return {x, y};
  }

  // Where rectangle r of a w x h source lands in the output.
  Rect map(const Rect& r, int64_t w, int64_t h) const;

  // A view-space normal's x, y (x right, y up) as the output sees the surface: the image turns, so its normals
  // turn with it. In image axes (right, down) the vector is (x, -y); the pixel map moves it by mirroring
  // (flips negate a component), then transposing (swaps them).
  std::pair<float, float> turn_normal(float x, float y) const {
    float u = x, v = -y;
    if (flip_x) u = -u;
    if (flip_y) v = -v;
    if (transpose) std::swap(u, v);
    return {u, -v};
  }
};

// `src` under `d`. With normal_plane >= 0, that plane and the next hold a view-space normal's x, y, turned with
// the image (Dihedral::turn_normal).
Image apply(const Image& src, const Dihedral& d, int normal_plane = -1);

}  // namespace residue
