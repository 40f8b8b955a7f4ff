#include "core/temporal/reprojection.h"

#include <cmath>
#include <string>

#include <tbb/parallel_for.h>

#include "core/util/error.h"

namespace residue {
namespace {

float finite_or_zero(float v) { return std::isfinite(v) ? v : 0.0f; }

void check_same_size(const Image& a, const Image& b, const char* what) {
  if (a.width() != b.width() || a.height() != b.height())
    throw Error(ErrorKind::Usage, std::string("reprojection: the ") + what + " is " + std::to_string(b.width()) + "x" +
                                      std::to_string(b.height()) + ", the frame " + std::to_string(a.width()) + "x" +
                                      std::to_string(a.height()));
}

}  // namespace

Image motion_from_cycles_vector(const Image& vector) {
  if (vector.channels() < 4)
    throw Error(ErrorKind::Usage, "Cycles' Vector pass has 4 channels, not " + std::to_string(vector.channels()));
  Image m(vector.width(), vector.height(), 4);
  for (int64_t y = 0; y < vector.height(); ++y)
    for (int64_t x = 0; x < vector.width(); ++x) {
      m.at(x, y, 0) = finite_or_zero(vector.at(x, y, 0));   // previous - pixel, x right
      m.at(x, y, 1) = -finite_or_zero(vector.at(x, y, 1));  // y up -> rows down
      m.at(x, y, 2) = -finite_or_zero(vector.at(x, y, 2));  // pixel - next -> next - pixel
      m.at(x, y, 3) = finite_or_zero(vector.at(x, y, 3));   // and y up -> rows down: -(-W)
    }
  return m;
}

Reprojected reproject(const Image& neighbour, const Image& motion, MotionStep step, const Image* depth_t,
                      const Image* depth_neighbour, const Image* normal_t, const Image* normal_neighbour,
                      const ReprojectionOptions& options) {
  check_same_size(neighbour, motion, "motion");
  if (motion.channels() < 4)
    throw Error(ErrorKind::Usage, "reprojection: motion has 4 channels (previous x, y; next x, y), not " +
                                      std::to_string(motion.channels()));
  const bool depth_test = depth_t && depth_neighbour;
  const bool normal_test = normal_t && normal_neighbour;
  if (depth_test) check_same_size(neighbour, *depth_t, "depth"), check_same_size(neighbour, *depth_neighbour, "depth");
  if (normal_test)
    check_same_size(neighbour, *normal_t, "normal"), check_same_size(neighbour, *normal_neighbour, "normal");
  const int64_t W = neighbour.width(), H = neighbour.height();
  const int C = neighbour.channels(), first = step == MotionStep::Previous ? 0 : 2;
  Reprojected r{Image(W, H, C), Image(W, H, 1), 0, 0};
  std::vector<uint8_t> state(static_cast<size_t>(W * H), 0);  // 0 valid, 1 outside, 2 disoccluded
  tbb::parallel_for(int64_t{0}, H, [&](int64_t y) {
    for (int64_t x = 0; x < W; ++x) {
      const double sx = static_cast<double>(x) + motion.at(x, y, first);
      const double sy = static_cast<double>(y) + motion.at(x, y, first + 1);
      const double fx = std::floor(sx), fy = std::floor(sy);
      const int64_t x0 = static_cast<int64_t>(fx), y0 = static_cast<int64_t>(fy);
      const double ax = sx - fx, ay = sy - fy;
      // The taps that carry weight; a sample on a pixel centre needs only that pixel (an integer motion is exact).
      const int64_t x1 = ax > 0 ? x0 + 1 : x0, y1 = ay > 0 ? y0 + 1 : y0;
      uint8_t& s = state[static_cast<size_t>(y * W + x)];
      if (!(std::isfinite(sx) && std::isfinite(sy)) || x0 < 0 || y0 < 0 || x1 >= W || y1 >= H) {
        s = 1;
        continue;
      }
      const int64_t tx[4] = {x0, x1, x0, x1}, ty[4] = {y0, y0, y1, y1};
      const double w[4] = {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay};
      for (int k = 0; k < 4 && s == 0; ++k) {
        if (w[k] == 0) continue;
        bool background = false;  // the environment in both (depth 0: no hit), which has no normal to compare
        if (depth_test) {
          const double zt = depth_t->at(x, y), zn = depth_neighbour->at(tx[k], ty[k]);
          background = zt == 0 && zn == 0;
          if (!(std::abs(zn - zt) <= options.depth_tolerance * std::max(std::abs(zt), 1e-6))) s = 2;
        }
        if (normal_test && s == 0 && !background) {
          double dot = 0;
          for (int c = 0; c < 3; ++c) dot += double{normal_t->at(x, y, c)} * normal_neighbour->at(tx[k], ty[k], c);
          if (!(dot >= options.normal_min_dot)) s = 2;
        }
      }
      if (s != 0) continue;
      r.valid.at(x, y) = 1.0f;
      for (int c = 0; c < C; ++c) {
        double v = 0;
        for (int k = 0; k < 4; ++k)
          if (w[k] != 0) v += w[k] * neighbour.at(tx[k], ty[k], c);
        r.image.at(x, y, c) = static_cast<float>(v);
      }
    }
  });
  for (uint8_t s : state) r.outside += s == 1, r.disoccluded += s == 2;
  return r;
}

}  // namespace residue
