#include "core/denoise/engine/tile_runner.h"

#include <cmath>
#include <cstring>
#include <string>

#include "core/denoise/engine/tiling.h"
#include "core/denoise/output_guard.h"
#include "core/denoise/variance_blend.h"
#include "core/image/dihedral.h"
#include "core/util/error.h"

namespace residue {
namespace {

bool colour_is_empty(const Image& colour, const Rect& r) {
  for (int64_t y = r.y; y < r.y + r.height; ++y)
    for (int64_t x = r.x; x < r.x + r.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const float v = colour.at(x, y, c);
        if (std::isfinite(v) && v > 0.0f) return false;
      }
  return true;
}

}  // namespace

int64_t NetworkPass::work_per_pixel() const {
  return static_cast<int64_t>(std::ceil(model->graph.flops_per_pixel())) * ensemble;
}

bool TileRunner::run(const AovStack& src, const Rect& src_rect, const Rect& bounds, const Rect& t, Image& out,
                     int64_t out_x0, int64_t out_y0) {
  throw_if_cancelled(cancel_);
  const nn::Graph& g = pass_.model->graph;
  const int64_t halo = g.halo(), align = g.alignment();
  Rect in = expand(t, halo, bounds, align);
  in.x -= src_rect.x;
  in.y -= src_rect.y;
  const int64_t tx = t.x - src_rect.x, ty = t.y - src_rect.y;
  const int oc = out.channels();
  if (pass_.skip_empty && colour_is_empty(src.color.image, in)) {
    for (int64_t y = t.y; y < t.y + t.height; ++y)
      std::memset(&out.at(t.x - out_x0, y - out_y0, 0), 0, static_cast<size_t>(t.width * oc) * sizeof(float));
    return true;
  }
  io_.input(src, in, features_);
  // Networks that pool take tiles of whole multiples of their alignment: zeros past the image's edge, as
  // when the whole image is padded.
  const Image* net_in = &features_;
  if (in.width % align != 0 || in.height % align != 0) {
    padded_ = Image((in.width + align - 1) / align * align, (in.height + align - 1) / align * align, features_.channels());
    for (int64_t y = 0; y < in.height; ++y)
      std::memcpy(&padded_.at(0, y, 0), features_.row(y).data(), static_cast<size_t>(in.width * features_.channels()) * sizeof(float));
    net_in = &padded_;
  }
  const Rect core{tx - in.x, ty - in.y, t.width, t.height};  // the tile in the network's input, without its halo
  // The self-ensemble: the network on the tile under each flip (and transpose), each output turned back; the
  // mean of their linear values. Member 0 is the tile as it is.
  int64_t non_finite = 0;
  const int ensemble = pass_.ensemble;
  const float weight = 1.0f / static_cast<float>(ensemble);
  for (int k = 0; k < ensemble; ++k) {
    if (k == 0) {
      backend_.run(*net_in, result_, cancel_, core);
    } else {
      const Dihedral d = Dihedral::from_index(k);
      turned_in_ = apply(*net_in, d, pass_.turned_normal_plane);
      backend_.run(turned_in_, turned_out_, cancel_, d.map(core, net_in->width(), net_in->height()));
      result_ = apply(turned_out_, d.inverse());
    }
    if (pass_.guard) guarded_ += guard_output(features_, core, halo, result_);
    for (int64_t y = 0; y < t.height; ++y)
      for (int64_t x = 0; x < t.width; ++x)
        for (int c = 0; c < oc; ++c) {
          const float raw = result_.at(core.x + x, core.y + y, c);
          non_finite += !std::isfinite(raw);
          const float v = io_.output(raw, src, tx + x, ty + y, c);
          float& o = out.at(t.x - out_x0 + x, t.y - out_y0 + y, c);
          o = (k == 0 ? 0.0f : o) + weight * v;  // one member: weight 1, v itself
        }
  }
  // Output is finite or the run fails: a network whose weights or inputs overflow does not get written as a
  // black or saturated image with success (the output transforms would turn NaN into 0 and Inf into FLT_MAX).
  if (non_finite > 0)
    throw Error(ErrorKind::Input, "model " + pass_.model->name + " gave " + std::to_string(non_finite) +
                                      " non-finite output values in the tile " + t.to_string() +
                                      " (its weights or the render's values overflow fp32); nothing was written");
  if (pass_.blend_tau > 0 && src.variance)
    blend_by_variance(src, src_rect, bounds, t, out, out_x0, out_y0, pass_.blend_tau);
  return false;
}

}  // namespace residue
