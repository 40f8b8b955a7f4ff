#include "core/metrics/flip.h"

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/metrics/tile_scores.h"
#include "core/util/error.h"

namespace residue::metrics {
namespace {

using Plane = std::vector<double>;  // one channel, row by row
constexpr double kPi = std::numbers::pi;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// --- colour spaces (sRGB primaries, D65) -----------------------------------------------------------------------

constexpr double kRgbToXyz[3][3] = {
    {10135552.0 / 24577794.0, 8788810.0 / 24577794.0, 4435075.0 / 24577794.0},
    {2613072.0 / 12288897.0, 8788810.0 / 12288897.0, 887015.0 / 12288897.0},
    {1425312.0 / 73733382.0, 8788810.0 / 73733382.0, 70074185.0 / 73733382.0}};
constexpr double kXyzToRgb[3][3] = {{3.241003275, -1.537398934, -0.498615861},
                                    {-0.969224334, 1.875930071, 0.041554224},
                                    {0.055639423, -0.204011202, 1.057148933}};
constexpr double kWhite[3] = {0.950428545, 1.0, 1.088900371};
constexpr double kInverseWhite[3] = {1.052156925, 1.0, 0.918357670};

void rgb_to_xyz(const double rgb[3], double xyz[3]) {
  for (int r = 0; r < 3; ++r) xyz[r] = kRgbToXyz[r][0] * rgb[0] + kRgbToXyz[r][1] * rgb[1] + kRgbToXyz[r][2] * rgb[2];
}

// YCxCz: a linear opponent space (no cube root), white-normalised.
void rgb_to_ycxcz(const double rgb[3], double out[3]) {
  double xyz[3];
  rgb_to_xyz(rgb, xyz);
  const double x = xyz[0] * kInverseWhite[0], y = xyz[1] * kInverseWhite[1], z = xyz[2] * kInverseWhite[2];
  out[0] = 116.0 * y - 16.0;
  out[1] = 500.0 * (x - y);
  out[2] = 200.0 * (y - z);
}

void ycxcz_to_rgb(const double in[3], double rgb[3]) {
  const double y = (in[0] + 16.0) / 116.0, x = y + in[1] / 500.0, z = y - in[2] / 200.0;
  const double xyz[3] = {x * kWhite[0], y * kWhite[1], z * kWhite[2]};
  for (int r = 0; r < 3; ++r) rgb[r] = kXyzToRgb[r][0] * xyz[0] + kXyzToRgb[r][1] * xyz[1] + kXyzToRgb[r][2] * xyz[2];
}

// CIE L*a*b* with the Hunt adjustment (a and b scaled by 0.01 L).
void rgb_to_lab_hunt(const double rgb[3], double out[3]) {
  double xyz[3];
  rgb_to_xyz(rgb, xyz);
  constexpr double delta = 6.0 / 29.0;
  const auto f = [](double t) {
    return t > delta * delta * delta ? std::cbrt(t) : t / (3.0 * delta * delta) + 4.0 / 29.0;
  };
  const double fx = f(xyz[0] * kInverseWhite[0]), fy = f(xyz[1] * kInverseWhite[1]), fz = f(xyz[2] * kInverseWhite[2]);
  const double l = 116.0 * fy - 16.0;
  out[0] = l;
  out[1] = 0.01 * l * 500.0 * (fx - fy);
  out[2] = 0.01 * l * 200.0 * (fy - fz);
}

double hyab(const double a[3], const double b[3]) {
  return std::abs(a[0] - b[0]) + std::sqrt((a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

constexpr double kQc = 0.7, kPc = 0.4, kPt = 0.95;  // the colour error's power and its remap to [0, 1]

// The largest colour difference: pure green against pure blue, Hunt-adjusted HyAB to the power q_c.
double colour_max() {
  const double green[3] = {0, 1, 0}, blue[3] = {0, 0, 1};
  double a[3], b[3];
  rgb_to_lab_hunt(green, a);
  rgb_to_lab_hunt(blue, b);
  return std::pow(hyab(a, b), kQc);
}

// fn(i) for every pixel index in [0, n), in parallel.
template <typename F>
void each_pixel(size_t n, F&& fn) {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) fn(i);
  });
}

// --- separable filters, borders clamped to the edge -----------------------------------------------------------

struct Taps {
  int radius = 0;
  std::vector<double> w;  // w[i + radius] for offset i
};

void scale_to_sum(std::vector<double>& w, double sum) {
  for (double& v : w) v /= sum;
}

// out(x, y) = sum over i of w(i) in(clamp(x + i), y): along x when `along_x`, else along y. Written as one
// multiply-add of a whole row per tap, which the compiler vectorises; only the columns within the radius of the
// left and right borders clamp.
void filter(const Plane& in, Plane& out, int64_t width, int64_t height, const Taps& t, bool along_x) {
  out.assign(in.size(), 0.0);
  const int r = t.radius;
  tbb::parallel_for(tbb::blocked_range<int64_t>(0, height, 8), [&](const tbb::blocked_range<int64_t>& rows) {
    for (int64_t y = rows.begin(); y != rows.end(); ++y) {
      double* o = out.data() + y * width;
      if (!along_x) {
        for (int i = -r; i <= r; ++i) {
          const double wi = t.w[static_cast<size_t>(i + r)];
          const double* src = in.data() + std::clamp<int64_t>(y + i, 0, height - 1) * width;
          for (int64_t x = 0; x < width; ++x) o[x] += wi * src[x];
        }
        continue;
      }
      const double* src = in.data() + y * width;
      const int64_t lo = std::min<int64_t>(r, width), hi = std::max<int64_t>(lo, width - r);  // [lo, hi): no clamp
      for (int i = -r; i <= r; ++i) {
        const double wi = t.w[static_cast<size_t>(i + r)];
        for (int64_t x = lo; x < hi; ++x) o[x] += wi * src[x + i];
      }
      for (int64_t x = 0; x < width; ++x) {
        if (x == lo) x = hi;
        if (x >= width) break;
        double sum = 0.0;
        for (int i = -r; i <= r; ++i) sum += t.w[static_cast<size_t>(i + r)] * src[std::clamp<int64_t>(x + i, 0, width - 1)];
        o[x] = sum;
      }
    }
  });
}

Plane separable(const Plane& in, int64_t width, int64_t height, const Taps& along_x, const Taps& along_y) {
  Plane tmp, out;
  filter(in, tmp, width, height, along_x, true);
  filter(tmp, out, width, height, along_y, false);
  return out;
}

// The contrast sensitivity functions of the three YCxCz channels, sampled in degrees (offset i at i / ppd), one
// radius for all from the widest. Cz's is a sum of two Gaussians, normalised together.
struct CsfTaps {
  Taps y, cx, cz1, cz2;
};

CsfTaps csf_taps(double ppd) {
  const int r = static_cast<int>(std::ceil(3.0 * std::sqrt(0.04 / (2.0 * kPi * kPi)) * ppd));
  const auto gauss = [&](double a, double b, bool root) {
    Taps t{r, std::vector<double>(static_cast<size_t>(2 * r + 1))};
    const double c = a * std::sqrt(kPi / b);
    for (int i = -r; i <= r; ++i) {
      const double u = i / ppd;
      t.w[static_cast<size_t>(i + r)] = (root ? std::sqrt(c) : c) * std::exp(-kPi * kPi * u * u / b);
    }
    return t;
  };
  CsfTaps k{gauss(1.0, 0.0047, false), gauss(1.0, 0.0053, false), gauss(34.1, 0.04, true), gauss(13.5, 0.025, true)};
  const auto sum = [](const Taps& t) {
    double s = 0;
    for (double v : t.w) s += v;
    return s;
  };
  scale_to_sum(k.y.w, sum(k.y));
  scale_to_sum(k.cx.w, sum(k.cx));
  const double s1 = sum(k.cz1), s2 = sum(k.cz2), n = std::sqrt(s1 * s1 + s2 * s2);
  scale_to_sum(k.cz1.w, n);
  scale_to_sum(k.cz2.w, n);
  return k;
}

// The feature detectors: a Gaussian of 0.082 degrees' width (in pixels) and its first (edge) and second (point)
// derivatives, each derivative's positive taps scaled to sum +1 and its negative taps to sum -1.
struct FeatureTaps {
  Taps gauss, edge, point;
};

FeatureTaps feature_taps(double ppd) {
  const double sigma = 0.5 * 0.082 * ppd;
  const int r = static_cast<int>(std::ceil(3.0 * sigma));
  FeatureTaps k;
  for (Taps* t : {&k.gauss, &k.edge, &k.point}) *t = {r, std::vector<double>(static_cast<size_t>(2 * r + 1))};
  double g_sum = 0;
  for (int i = -r; i <= r; ++i) {
    const double g = std::exp(-static_cast<double>(i * i) / (2.0 * sigma * sigma));
    const auto at = static_cast<size_t>(i + r);
    k.gauss.w[at] = g;
    k.edge.w[at] = -i * g;
    k.point.w[at] = (i * i / (sigma * sigma) - 1.0) * g;
    g_sum += g;
  }
  scale_to_sum(k.gauss.w, g_sum);
  for (Taps* t : {&k.edge, &k.point}) {
    double pos = 0, neg = 0;
    for (double v : t->w) (v > 0 ? pos : neg) += v;
    for (double& v : t->w) v = v > 0 ? v / pos : v < 0 ? v / -neg : 0.0;
  }
  return k;
}

// --- LDR-FLIP on linear RGB in [0, 1] --------------------------------------------------------------------------

struct Rgb {
  Plane c[3];
  int64_t width = 0, height = 0;
};

// What FLIP compares of one image: its CSF-filtered colour (Hunt-adjusted L*a*b*) and the magnitudes of its edges
// and points.
struct Seen {
  Plane lab[3], edge, point;
};

// Planes are released as soon as they are used, so that the peak stays near a dozen planes per image.
Seen seen(const Rgb& img, const CsfTaps& csf, const FeatureTaps& ft) {
  const int64_t w = img.width, h = img.height;
  const auto n = static_cast<size_t>(w * h);
  const auto release = [](Plane& p) { Plane().swap(p); };
  Plane ycc[3];
  for (Plane& p : ycc) p.resize(n);
  each_pixel(n, [&](size_t i) {
    const double rgb[3] = {img.c[0][i], img.c[1][i], img.c[2][i]};
    double o[3];
    rgb_to_ycxcz(rgb, o);
    for (int c = 0; c < 3; ++c) ycc[c][i] = o[c];
  });
  Plane lum(n);  // the unfiltered Y_o, normalised to [0, 1]: the features' input
  each_pixel(n, [&](size_t i) { lum[i] = (ycc[0][i] + 16.0) / 116.0; });
  Plane f[3];
  f[0] = separable(ycc[0], w, h, csf.y, csf.y);
  release(ycc[0]);
  f[1] = separable(ycc[1], w, h, csf.cx, csf.cx);
  release(ycc[1]);
  f[2] = separable(ycc[2], w, h, csf.cz1, csf.cz1);
  {
    const Plane second = separable(ycc[2], w, h, csf.cz2, csf.cz2);
    each_pixel(n, [&](size_t i) { f[2][i] += second[i]; });
  }
  release(ycc[2]);

  Seen s;
  for (Plane& p : s.lab) p.resize(n);
  each_pixel(n, [&](size_t i) {
    const double filtered[3] = {f[0][i], f[1][i], f[2][i]};
    double rgb[3], lab[3];
    ycxcz_to_rgb(filtered, rgb);
    for (double& v : rgb) v = std::clamp(v, 0.0, 1.0);
    rgb_to_lab_hunt(rgb, lab);
    for (int c = 0; c < 3; ++c) s.lab[c][i] = lab[c];
  });
  for (Plane& p : f) release(p);

  // Edges and points: (derivative along x, Gaussian along y) and (Gaussian along x, derivative along y).
  Plane gx;
  filter(lum, gx, w, h, ft.gauss, true);
  const auto magnitude = [&](const Taps& d, Plane& out) {
    Plane dx, x_part, y_part;
    filter(lum, dx, w, h, d, true);
    filter(dx, x_part, w, h, ft.gauss, false);
    release(dx);
    filter(gx, y_part, w, h, d, false);
    out.resize(n);
    each_pixel(n, [&](size_t i) { out[i] = std::sqrt(x_part[i] * x_part[i] + y_part[i] * y_part[i]); });
  };
  magnitude(ft.edge, s.edge);
  magnitude(ft.point, s.point);
  return s;
}

// The per-pixel LDR-FLIP error of `test` against `reference`, both linear RGB in [0, 1].
Plane ldr_map(const Rgb& test, const Rgb& reference, double ppd) {
  const CsfTaps csf = csf_taps(ppd);
  const FeatureTaps ft = feature_taps(ppd);
  const Seen r = seen(reference, csf, ft), t = seen(test, csf, ft);
  const double cmax = colour_max(), pccmax = kPc * cmax;
  Plane e(r.edge.size());
  each_pixel(e.size(), [&](size_t i) {
    const double a[3] = {r.lab[0][i], r.lab[1][i], r.lab[2][i]}, b[3] = {t.lab[0][i], t.lab[1][i], t.lab[2][i]};
    const double d = std::pow(hyab(a, b), kQc);
    const double colour = d < pccmax ? d * (kPt / pccmax) : kPt + ((d - pccmax) / (cmax - pccmax)) * (1.0 - kPt);
    const double feature = std::sqrt(std::max(std::abs(r.edge[i] - t.edge[i]), std::abs(r.point[i] - t.point[i])) /
                                     std::numbers::sqrt2);
    e[i] = std::pow(colour, 1.0 - feature);
  });
  return e;
}

// --- inputs, pooling ---------------------------------------------------------------------------------------------

void check_inputs(const Image& test, const Image& reference, const FlipOptions& options) {
  if (test.width() != reference.width() || test.height() != reference.height())
    throw Error(ErrorKind::Usage, "FLIP: the test image is " + std::to_string(test.width()) + "x" +
                                      std::to_string(test.height()) + " but the reference is " +
                                      std::to_string(reference.width()) + "x" + std::to_string(reference.height()) +
                                      "; both must have the same size");
  if (test.channels() < 3 || reference.channels() < 3)
    throw Error(ErrorKind::Usage, "FLIP: both images need at least 3 channels (RGB)");
  if (!(options.pixels_per_degree > 0) || !std::isfinite(options.pixels_per_degree))
    throw Error(ErrorKind::Usage, "FLIP: pixels per degree must be a positive number");
}

// Whether a pixel's RGB is finite: the metrics' own test (tile_scores.h), so FLIP leaves out the pixels they do.
bool finite_rgb(const Image& img, int64_t x, int64_t y) {
  return detail::finite_rgb(img.row(y).data() + x * img.channels());
}

// The RGB planes of `img` with excluded pixels (`keep` false) read as 0.
Rgb planes(const Image& img, const std::vector<char>& keep) {
  Rgb p;
  p.width = img.width();
  p.height = img.height();
  const auto n = static_cast<size_t>(p.width * p.height);
  for (Plane& c : p.c) c.resize(n);
  for (int64_t y = 0; y < p.height; ++y)
    for (int64_t x = 0; x < p.width; ++x) {
      const auto i = static_cast<size_t>(y * p.width + x);
      for (int c = 0; c < 3; ++c) p.c[c][i] = keep[i] ? static_cast<double>(img.at(x, y, c)) : 0.0;
    }
  return p;
}

std::vector<char> finite_pixels(const Image& test, const Image& reference) {
  std::vector<char> keep(static_cast<size_t>(test.width() * test.height()));
  for (int64_t y = 0; y < test.height(); ++y)
    for (int64_t x = 0; x < test.width(); ++x)
      keep[static_cast<size_t>(y * test.width() + x)] = finite_rgb(test, x, y) && finite_rgb(reference, x, y);
  return keep;
}

FlipResult pooled(const Plane& map, const std::vector<char>& keep, int64_t width, int64_t height) {
  FlipResult r;
  r.map = Image(width, height, 1);
  double sum = 0;
  for (int64_t y = 0; y < height; ++y)
    for (int64_t x = 0; x < width; ++x) {
      const auto i = static_cast<size_t>(y * width + x);
      if (!keep[i]) {
        r.map.at(x, y, 0) = std::numeric_limits<float>::quiet_NaN();
        ++r.excluded;
        continue;
      }
      r.map.at(x, y, 0) = static_cast<float>(map[i]);
      sum += map[i];
      ++r.pixels;
    }
  r.mean = r.pixels > 0 ? sum / static_cast<double>(r.pixels) : kNaN;
  return r;
}

// Narkowicz's fitted ACES curve on 0.6 x (the 0.6 cancels the fit's own exposure).
constexpr double kAces[6] = {0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14};

double aces(double x) {
  return (kAces[0] * x * x + kAces[1] * x + kAces[2]) / (kAces[3] * x * x + kAces[4] * x + kAces[5]);
}

// The value the ACES curve maps to 0.85: the larger root of the curve's equation.
double aces_x_at(double t) {
  const double a = kAces[0] - t * kAces[3], b = kAces[1] - t * kAces[4], c = kAces[2] - t * kAces[5];
  const double d1 = -0.5 * (b / a);
  return d1 + std::sqrt(d1 * d1 - c / a);
}

}  // namespace

FlipResult ldr_flip(const Image& test, const Image& reference, const FlipOptions& options) {
  check_inputs(test, reference, options);
  const std::vector<char> keep = finite_pixels(test, reference);
  Rgb t = planes(test, keep), r = planes(reference, keep);
  for (Rgb* p : {&t, &r})
    for (Plane& c : p->c)
      for (double& v : c) v = std::clamp(v, 0.0, 1.0);
  return pooled(ldr_map(t, r, options.pixels_per_degree), keep, test.width(), test.height());
}

FlipExposures flip_exposures(const Image& reference, const FlipOptions& options) {
  std::vector<double> lum;
  lum.reserve(static_cast<size_t>(reference.width() * reference.height()));
  for (int64_t y = 0; y < reference.height(); ++y)
    for (int64_t x = 0; x < reference.width(); ++x)
      if (finite_rgb(reference, x, y))
        lum.push_back(0.2126 * reference.at(x, y, 0) + 0.7152 * reference.at(x, y, 1) + 0.0722 * reference.at(x, y, 2));
  const auto median_of = [](std::vector<double> v) {
    auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
  };
  const double x_max = aces_x_at(0.85);
  FlipExposures e;
  if (!options.start_exposure || !options.stop_exposure) {
    const double max = lum.empty() ? 0.0 : *std::max_element(lum.begin(), lum.end());
    if (!(max > 0))
      throw Error(ErrorKind::Usage, "HDR-FLIP: the reference has no pixel of positive luminance to set the "
                                    "exposures by; give them (start and stop)");
    double median = median_of(lum);
    if (!(median > 0)) {  // half of the image black: the median of the lit pixels
      std::vector<double> lit;
      for (double v : lum)
        if (v > 0) lit.push_back(v);
      median = median_of(std::move(lit));
    }
    e.start = std::log2(x_max / max);
    e.stop = std::log2(x_max / median);
  }
  if (options.start_exposure) e.start = *options.start_exposure;
  if (options.stop_exposure) e.stop = *options.stop_exposure;
  if (!std::isfinite(e.start) || !std::isfinite(e.stop) || e.start > e.stop)
    throw Error(ErrorKind::Usage, "HDR-FLIP: the start exposure (" + std::to_string(e.start) +
                                      ") must be finite and no later than the stop (" + std::to_string(e.stop) + ")");
  e.count = options.exposures ? *options.exposures : std::max(2, static_cast<int>(std::ceil(e.stop - e.start)));
  if (e.count < 2) throw Error(ErrorKind::Usage, "HDR-FLIP: at least 2 exposures, not " + std::to_string(e.count));
  return e;
}

FlipResult hdr_flip(const Image& test, const Image& reference, const FlipOptions& options) {
  check_inputs(test, reference, options);
  const FlipExposures e = flip_exposures(reference, options);
  const std::vector<char> keep = finite_pixels(test, reference);
  const Rgb t = planes(test, keep), r = planes(reference, keep);
  const auto n = t.c[0].size();
  Plane worst(n, 0.0), at(n, 0.0);
  const double step = (e.stop - e.start) / (e.count - 1);
  for (int k = 0; k < e.count; ++k) {
    const double scale = std::exp2(e.start + k * step);
    Rgb te = t, re = r;
    for (Rgb* p : {&te, &re})
      for (Plane& c : p->c) each_pixel(n, [&](size_t i) { c[i] = std::clamp(aces(c[i] * scale), 0.0, 1.0); });
    const Plane map = ldr_map(te, re, options.pixels_per_degree);
    for (size_t i = 0; i < n; ++i)
      if (map[i] > worst[i]) {  // the first exposure that reaches the maximum keeps it
        worst[i] = map[i];
        at[i] = static_cast<double>(k) / (e.count - 1);
      }
  }
  FlipResult result = pooled(worst, keep, test.width(), test.height());
  result.exposures = e;
  result.exposure_map = Image(test.width(), test.height(), 1);
  for (int64_t y = 0; y < test.height(); ++y)
    for (int64_t x = 0; x < test.width(); ++x) {
      const auto i = static_cast<size_t>(y * test.width() + x);
      result.exposure_map.at(x, y, 0) = keep[i] ? static_cast<float>(at[i]) : std::numeric_limits<float>::quiet_NaN();
    }
  return result;
}

double flip_mean(const Image& map, const std::optional<Rect>& region) {
  const Rect r = region.value_or(map.bounds());
  double sum = 0;
  int64_t n = 0;
  for (int64_t y = r.y; y < r.y + r.height; ++y)
    for (int64_t x = r.x; x < r.x + r.width; ++x)
      if (const float v = map.at(x, y, 0); !std::isnan(v)) {
        sum += v;
        ++n;
      }
  return n > 0 ? sum / static_cast<double>(n) : kNaN;
}

std::string flip_formula_text(const FlipExposures& e) {
  char range[96];
  std::snprintf(range, sizeof range, "%.4f to %.4f in %d steps", e.start, e.stop, e.count);
  return std::string("HDR-FLIP (NVIDIA's FLIP, Andersson et al. 2020 and 2021, as its reference code v1.6 computes "
                     "it): per pixel, the largest LDR-FLIP error over exposures 2^c of both images, c from ") +
         range + " (set by the reference's maximum and median luminance), each tone mapped with ACES and clamped to "
         "[0, 1]; LDR-FLIP is the HyAB colour difference of the images filtered by the eye's contrast sensitivity at "
         "67.02 pixels per degree, raised to the power of one minus their edge and point difference; the score is the "
         "mean of the map, pixels that are not finite left out.";
}

}  // namespace residue::metrics
