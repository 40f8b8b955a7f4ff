// Image metrics against independent references: naive float64 loops written here (no separability, no
// tiles), the relMSE stored in the starter scenes' scene.json, and scikit-image (tests/reference/
// skimage_metrics.py, live when Debian's python has it, and a stored fixture otherwise).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <nlohmann/json.hpp>
#include <tbb/task_arena.h>

#include "core/metrics/metrics.h"
#include "core/metrics/tonemap.h"
#include "core/util/error.h"
#include "support/test_support.h"

namespace {

namespace fs = std::filesystem;
using residue::Error;
using residue::ErrorKind;
using residue::Image;
using residue::Rect;
using residue::metrics::MapKind;
using residue::metrics::Options;
using residue::metrics::Scores;
using residue::metrics::SsimSpace;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
constexpr float kInff = std::numeric_limits<float>::infinity();
const char* const kCombined[3] = {"ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B"};

// ---------------------------------------------------------------------------------------------------------
// Independent references
// ---------------------------------------------------------------------------------------------------------

// Hable filmic normalised at 11.2, then sRGB, written out again from the formula (not the library's code).
double naive_tonemap(double x) {
  if (std::isnan(x) || x <= 0) return 0;
  if (x >= 11.2) return 1;
  auto f = [](double v) {
    return ((v * (0.15 * v + 0.10 * 0.50) + 0.20 * 0.02) / (v * (0.15 * v + 0.50) + 0.20 * 0.30)) - 0.02 / 0.30;
  };
  const double t = std::clamp(f(x) / f(11.2), 0.0, 1.0);
  return std::clamp(t < 0.0031308 ? 12.92 * t : 1.055 * std::pow(t, 1 / 2.4) - 0.055, 0.0, 1.0);
}

bool finite_rgb(const Image& im, int64_t x, int64_t y) {
  return std::isfinite(im.at(x, y, 0)) && std::isfinite(im.at(x, y, 1)) && std::isfinite(im.at(x, y, 2));
}

bool valid_pixel(const Image& t, const Image& r, int64_t x, int64_t y) {
  return finite_rgb(t, x, y) && finite_rgb(r, x, y);
}

struct NaivePoint {
  double mse = 0, relmse = 0, psnr = 0;
  int64_t pixels = 0;
};

// Plain double loops over the region, skipping pixels not finite in either image.
NaivePoint naive_point(const Image& t, const Image& r, const Options& o) {
  const Rect region = o.roi.value_or(t.bounds());
  double se = 0, rse = 0, se_space = 0;
  NaivePoint out;
  for (int64_t y = region.y; y < region.y + region.height; ++y)
    for (int64_t x = region.x; x < region.x + region.width; ++x) {
      if (!valid_pixel(t, r, x, y)) continue;
      ++out.pixels;
      for (int c = 0; c < 3; ++c) {
        const double a = t.at(x, y, c), b = r.at(x, y, c);
        se += (a - b) * (a - b);
        rse += (a - b) * (a - b) / (b * b + o.eps);
        const double sa = o.ssim_space == SsimSpace::Tonemapped ? naive_tonemap(a) : a;
        const double sb = o.ssim_space == SsimSpace::Tonemapped ? naive_tonemap(b) : b;
        se_space += (sa - sb) * (sa - sb);
      }
    }
  const double n = 3.0 * static_cast<double>(out.pixels);
  out.mse = se / n;
  out.relmse = rse / n;
  out.psnr = se_space == 0 ? kInf : 10 * std::log10(1 / (se_space / n));
  return out;
}

using Window = std::array<std::array<double, 11>, 11>;

// The full 2-D Gaussian (sigma 1.5, 11x11), normalised to sum 1.
Window gauss2d() {
  Window g{};
  double total = 0;
  for (int dy = -5; dy <= 5; ++dy)
    for (int dx = -5; dx <= 5; ++dx) {
      const double w = std::exp(-(dx * dx + dy * dy) / (2 * 1.5 * 1.5));
      g[static_cast<size_t>(dy + 5)][static_cast<size_t>(dx + 5)] = w;
      total += w;
    }
  for (auto& row : g)
    for (double& w : row) w /= total;
  return g;
}

// One channel of an image in the SSIM space as doubles, NaN where the pixel is excluded.
std::vector<double> plane(const Image& im, const Image& t, const Image& r, int c, SsimSpace space) {
  std::vector<double> p(static_cast<size_t>(im.pixel_count()));
  for (int64_t y = 0; y < im.height(); ++y)
    for (int64_t x = 0; x < im.width(); ++x) {
      const double v = im.at(x, y, c);
      p[static_cast<size_t>(y * im.width() + x)] =
          !valid_pixel(t, r, x, y) ? std::nan("") : (space == SsimSpace::Tonemapped ? naive_tonemap(v) : v);
    }
  return p;
}

double ssim_formula(double mx, double my, double vx, double vy, double cxy) {
  const double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;
  return ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2));
}

// Textbook SSIM: direct 11x11 loops with the 2-D Gaussian at every pixel whose window lies inside the image,
// mean over those pixels and the three channels. No masks, no renormalisation, no separability.
double naive_ssim_standard(const Image& t, const Image& r, SsimSpace space) {
  const Window g = gauss2d();
  const int64_t w = t.width(), h = t.height();
  double sum = 0;
  int64_t n = 0;
  for (int c = 0; c < 3; ++c) {
    const std::vector<double> a = plane(t, t, r, c, space), b = plane(r, t, r, c, space);
    for (int64_t y = 5; y < h - 5; ++y)
      for (int64_t x = 5; x < w - 5; ++x) {
        double mx = 0, my = 0, sxx = 0, syy = 0, sxy = 0;
        for (int64_t dy = -5; dy <= 5; ++dy)
          for (int64_t dx = -5; dx <= 5; ++dx) {
            const double wt = g[static_cast<size_t>(dy + 5)][static_cast<size_t>(dx + 5)];
            const size_t i = static_cast<size_t>((y + dy) * w + x + dx);
            mx += wt * a[i];
            my += wt * b[i];
            sxx += wt * a[i] * a[i];
            syy += wt * b[i] * b[i];
            sxy += wt * a[i] * b[i];
          }
        sum += ssim_formula(mx, my, sxx - mx * mx, syy - my * my, sxy - mx * my);
        ++n;
      }
  }
  return sum / static_cast<double>(n);
}

// The masked definition, directly in 2-D: at each non-excluded pixel, moments with weights gauss * mask over
// the window cut at the image border, divided by the sum of those weights; mean over RGB. NaN where excluded.
std::vector<double> naive_ssim_map(const Image& t, const Image& r, SsimSpace space) {
  const Window g = gauss2d();
  const int64_t w = t.width(), h = t.height();
  std::vector<double> map(static_cast<size_t>(w * h), 0.0);
  for (int c = 0; c < 3; ++c) {
    const std::vector<double> a = plane(t, t, r, c, space), b = plane(r, t, r, c, space);
    for (int64_t y = 0; y < h; ++y)
      for (int64_t x = 0; x < w; ++x) {
        double ws = 0, mx = 0, my = 0, sxx = 0, syy = 0, sxy = 0;
        for (int64_t dy = -5; dy <= 5; ++dy)
          for (int64_t dx = -5; dx <= 5; ++dx) {
            const int64_t qx = x + dx, qy = y + dy;
            if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
            const size_t i = static_cast<size_t>(qy * w + qx);
            if (std::isnan(a[i])) continue;  // excluded
            const double wt = g[static_cast<size_t>(dy + 5)][static_cast<size_t>(dx + 5)];
            ws += wt;
            mx += wt * a[i];
            my += wt * b[i];
            sxx += wt * a[i] * a[i];
            syy += wt * b[i] * b[i];
            sxy += wt * a[i] * b[i];
          }
        const size_t p = static_cast<size_t>(y * w + x);
        if (std::isnan(a[p])) {
          map[p] = std::nan("");
          continue;
        }
        mx /= ws, my /= ws, sxx /= ws, syy /= ws, sxy /= ws;
        map[p] += ssim_formula(mx, my, sxx - mx * mx, syy - my * my, sxy - mx * my) / 3;
      }
  }
  return map;
}

// Mean of a full-image map over the region's non-excluded pixels at least 5 px from the image border; over
// all its non-excluded pixels when there are none.
double naive_ssim_score(const std::vector<double>& map, int64_t w, int64_t h, const Rect& region) {
  double interior = 0, all = 0;
  int64_t n_interior = 0, n_all = 0;
  for (int64_t y = region.y; y < region.y + region.height; ++y)
    for (int64_t x = region.x; x < region.x + region.width; ++x) {
      const double v = map[static_cast<size_t>(y * w + x)];
      if (std::isnan(v)) continue;
      all += v;
      ++n_all;
      if (x >= 5 && y >= 5 && x < w - 5 && y < h - 5) {
        interior += v;
        ++n_interior;
      }
    }
  return n_interior ? interior / static_cast<double>(n_interior) : all / static_cast<double>(n_all);
}

// A noisy copy of `ref`: ref + uniform noise in [-amount, amount).
Image noisy(const Image& ref, unsigned seed, float amount) {
  Image n = residue::testing::random_image(ref.width(), ref.height(), ref.channels(), seed, -amount, amount);
  for (size_t i = 0; i < n.size(); ++i) n.data()[i] += ref.data()[i];
  return n;
}

double rel_diff(double a, double b) { return std::abs(a - b) / std::max(std::abs(b), 1e-300); }

// The synthetic pair of tests/reference/skimage_metrics.py (--synthetic), bit for bit.
uint32_t hash32(uint32_t x, uint32_t y, uint32_t c, uint32_t seed) {
  uint32_t v = (x * 73856093u) ^ (y * 19349663u) ^ (c * 83492791u) ^ (seed * 2654435761u);
  v ^= v >> 13;
  v *= 0x5bd1e995u;
  v ^= v >> 15;
  return v;
}

std::pair<Image, Image> synthetic_pair(int64_t w, int64_t h) {
  Image test(w, h, 3), ref(w, h, 3);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x)
      for (uint32_t c = 0; c < 3; ++c) {
        const float r = static_cast<float>(hash32(x, y, c, 1) % 4096u) / 1024.0f;
        const float d = (static_cast<float>(hash32(x, y, c, 2) % 2048u) - 1024.0f) / 4096.0f;
        ref.at(x, y, static_cast<int>(c)) = r;
        test.at(x, y, static_cast<int>(c)) = r + d;
      }
  return {test, ref};
}

// Reads three named channels of an EXR with OpenImageIO directly (not through Residue's loaders).
Image read_rgb(const fs::path& path) {
  auto in = OIIO::ImageInput::open(path.string());
  if (!in) throw std::runtime_error("cannot open " + path.string() + ": " + OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  std::array<int, 3> index{};
  for (size_t c = 0; c < 3; ++c) {
    const auto it = std::find(spec.channelnames.begin(), spec.channelnames.end(), kCombined[c]);
    if (it == spec.channelnames.end()) throw std::runtime_error(path.string() + " lacks " + kCombined[c]);
    index[c] = static_cast<int>(it - spec.channelnames.begin());
  }
  std::vector<float> all(static_cast<size_t>(spec.width) * static_cast<size_t>(spec.height) *
                         static_cast<size_t>(spec.nchannels));
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data()))
    throw std::runtime_error("cannot read " + path.string() + ": " + in->geterror());
  Image out(spec.width, spec.height, 3);
  for (int64_t p = 0; p < out.pixel_count(); ++p)
    for (size_t c = 0; c < 3; ++c)
      out.data()[p * 3 + static_cast<int64_t>(c)] = all[static_cast<size_t>(p * spec.nchannels + index[c])];
  return out;
}

std::vector<fs::path> starter_scenes() {
  std::vector<fs::path> scenes;
  const fs::path root = residue::testing::shared_dataset("cycles-starter");
  if (root.empty()) return scenes;
  for (const auto& entry : fs::directory_iterator(root))
    if (fs::exists(entry.path() / "scene.json") && fs::exists(entry.path() / "noisy_a.exr"))
      scenes.push_back(entry.path());
  std::sort(scenes.begin(), scenes.end());
  return scenes;
}

nlohmann::json read_json(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

std::string quote(const std::string& s) {
  std::string out = "'";
  for (char ch : s) out += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
  return out + "'";
}

// Runs a shell command; returns its exit status and stdout.
int capture(const std::string& cmd, std::string& output) {
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return -1;
  std::array<char, 4096> buf{};
  size_t n = 0;
  while ((n = fread(buf.data(), 1, buf.size(), pipe)) > 0) output.append(buf.data(), n);
  return pclose(pipe);
}

const char* const kPython = "/usr/bin/python3";

fs::path skimage_script() {
  return fs::path(RESIDUE_TEST_FIXTURES).parent_path() / "reference" / "skimage_metrics.py";
}

bool python_has_skimage() {
  std::string ignored;
  return capture(std::string(kPython) + " -c 'import numpy, skimage.metrics, OpenImageIO' >/dev/null 2>&1",
                 ignored) == 0;
}

void expect_bitwise_equal(const Scores& a, const Scores& b) {
  EXPECT_EQ(a.mse, b.mse);
  EXPECT_EQ(a.relmse, b.relmse);
  EXPECT_EQ(a.psnr, b.psnr);
  EXPECT_EQ(a.ssim, b.ssim);
  EXPECT_EQ(a.pixels, b.pixels);
  EXPECT_EQ(a.excluded_test, b.excluded_test);
  EXPECT_EQ(a.excluded_reference, b.excluded_reference);
}

// ---------------------------------------------------------------------------------------------------------
// 1. Naive float64 references on random images
// ---------------------------------------------------------------------------------------------------------

TEST(MetricsNaive, MatchesNaiveDoubleLoopsInBothSpaces) {
  const Image ref = residue::testing::random_image(40, 33, 3, 11, 0.0f, 4.0f);
  const Image test = noisy(ref, 12, 0.4f);
  for (SsimSpace space : {SsimSpace::Tonemapped, SsimSpace::Linear}) {
    SCOPED_TRACE(space == SsimSpace::Tonemapped ? "tonemapped" : "linear");
    Options o;
    o.ssim_space = space;
    const Scores s = residue::metrics::compare(test, ref, o);
    const NaivePoint n = naive_point(test, ref, o);
    EXPECT_LT(rel_diff(s.mse, n.mse), 1e-12);
    EXPECT_LT(rel_diff(s.relmse, n.relmse), 1e-12);
    EXPECT_NEAR(s.psnr, n.psnr, 1e-9);
    const double naive = naive_ssim_standard(test, ref, space);
    EXPECT_NEAR(s.ssim, naive, 1e-6);
    EXPECT_NEAR(s.ssim, naive, 1e-12) << "separable/tiled sums should agree with direct 2-D sums to rounding";
    EXPECT_GT(s.ssim, 0.05);
    EXPECT_LT(s.ssim, 0.99);
    EXPECT_EQ(s.pixels, 40 * 33);
    EXPECT_EQ(s.excluded_test + s.excluded_reference, 0);
  }
}

TEST(MetricsNaive, UsesOnlyTheFirstThreeChannels) {
  const Image ref3 = residue::testing::random_image(23, 17, 3, 5, 0.0f, 2.0f);
  const Image test3 = noisy(ref3, 6, 0.2f);
  Image ref4(23, 17, 4, kNaNf), test4(23, 17, 4, kInff);  // garbage (non-finite) fourth channel
  for (int64_t y = 0; y < 17; ++y)
    for (int64_t x = 0; x < 23; ++x)
      for (int c = 0; c < 3; ++c) {
        ref4.at(x, y, c) = ref3.at(x, y, c);
        test4.at(x, y, c) = test3.at(x, y, c);
      }
  expect_bitwise_equal(residue::metrics::compare(test4, ref4), residue::metrics::compare(test3, ref3));
}

TEST(MetricsMaps, MatchNaivePerPixelValues) {
  const Image ref = residue::testing::random_image(31, 26, 3, 21, 0.0f, 3.0f);
  const Image test = noisy(ref, 22, 0.5f);
  const Options o;
  const Image abs_map = residue::metrics::error_map(test, ref, MapKind::AbsoluteError, o);
  const Image se_map = residue::metrics::error_map(test, ref, MapKind::SquaredError, o);
  const Image rse_map = residue::metrics::error_map(test, ref, MapKind::RelativeSquaredError, o);
  const Image ssim_map = residue::metrics::error_map(test, ref, MapKind::Ssim, o);
  const Image diff_map = residue::metrics::error_map(test, ref, MapKind::SignedDifference, o);
  for (const Image* m : {&abs_map, &se_map, &rse_map, &ssim_map, &diff_map}) {
    EXPECT_EQ(m->width(), 31);
    EXPECT_EQ(m->height(), 26);
    EXPECT_EQ(m->channels(), 1);
  }
  const std::vector<double> naive_ssim = naive_ssim_map(test, ref, SsimSpace::Tonemapped);
  for (int64_t y = 0; y < 26; ++y)
    for (int64_t x = 0; x < 31; ++x) {
      double a = 0, se = 0, rse = 0, diff = 0;
      for (int c = 0; c < 3; ++c) {
        const double d = double(test.at(x, y, c)) - double(ref.at(x, y, c));
        diff += d / 3;
        a += std::abs(d) / 3;
        se += d * d / 3;
        rse += d * d / (double(ref.at(x, y, c)) * double(ref.at(x, y, c)) + 0.01) / 3;
      }
      ASSERT_NEAR(abs_map.at(x, y), a, 1e-6 * std::max(1.0, a));
      ASSERT_NEAR(se_map.at(x, y), se, 1e-6 * std::max(1.0, se));
      ASSERT_NEAR(rse_map.at(x, y), rse, 1e-6 * std::max(1.0, rse));
      ASSERT_NEAR(diff_map.at(x, y), diff, 1e-6 * std::max(1.0, std::abs(diff)));
      // Includes border pixels, where the window is cut and renormalised.
      ASSERT_NEAR(ssim_map.at(x, y), naive_ssim[static_cast<size_t>(y * 31 + x)], 1e-6) << x << "," << y;
    }
}

// Tiles are 64 rows x 512 columns: an image crossing both seams, with excluded pixels on the seams.
TEST(MetricsTiles, LargeImageMatchesNaiveAcrossTileSeams) {
  const Image ref = residue::testing::random_image(530, 140, 3, 31, 0.0f, 2.0f);
  Image test = noisy(ref, 32, 0.3f);
  for (auto [x, y] : {std::pair<int64_t, int64_t>{511, 63}, {512, 64}, {100, 64}, {515, 10}, {529, 139}})
    test.at(x, y, 1) = kNaNf;
  const Scores s = residue::metrics::compare(test, ref);
  const std::vector<double> naive = naive_ssim_map(test, ref, SsimSpace::Tonemapped);
  EXPECT_NEAR(s.ssim, naive_ssim_score(naive, 530, 140, ref.bounds()), 1e-9);
  const NaivePoint n = naive_point(test, ref, Options{});
  EXPECT_LT(rel_diff(s.relmse, n.relmse), 1e-12);
  EXPECT_EQ(s.excluded_test, 5);
  const Image map = residue::metrics::error_map(test, ref, MapKind::Ssim);
  for (int64_t y = 0; y < 140; ++y)
    for (int64_t x = 0; x < 530; ++x) {
      const double expected = naive[static_cast<size_t>(y * 530 + x)];
      if (std::isnan(expected)) ASSERT_TRUE(std::isnan(map.at(x, y))) << x << "," << y;
      else ASSERT_NEAR(map.at(x, y), expected, 1e-6) << x << "," << y;
    }
}

// ---------------------------------------------------------------------------------------------------------
// 2. Real data: relMSE against scene.json
// ---------------------------------------------------------------------------------------------------------

TEST(MetricsRealData, RelMseMatchesSceneJsonOnEveryStarterScene) {
  const std::vector<fs::path> scenes = starter_scenes();
  if (scenes.empty()) GTEST_SKIP() << "shared data set cycles-starter not found beside the checkout";
  double worst = 0;
  for (const fs::path& dir : scenes) {
    SCOPED_TRACE(dir.string());
    const double expected = read_json(dir / "scene.json").at("metrics").at("relmse_noisy_a").get<double>();
    const Image test = read_rgb(dir / "noisy_a.exr");
    const Image ref = read_rgb(dir / "reference.exr");
    Options o;
    o.eps = 0.01;
    const Scores s = residue::metrics::compare(test, ref, o);
    EXPECT_EQ(s.pixels, test.pixel_count());
    EXPECT_LT(rel_diff(s.relmse, expected), 1e-6) << s.relmse << " vs " << expected;
    worst = std::max(worst, rel_diff(s.relmse, expected));
  }
  std::printf("[ metrics  ] %zu scenes, worst relative relMSE difference to scene.json: %.3g\n", scenes.size(),
              worst);
  RecordProperty("worst_relmse_rel_diff", std::to_string(worst));
}

// ---------------------------------------------------------------------------------------------------------
// 3. scikit-image: live on starter scenes, and a stored fixture
// ---------------------------------------------------------------------------------------------------------

TEST(MetricsSkimage, MatchesScikitImageOnStarterScenes) {
  const std::vector<fs::path> scenes = starter_scenes();
  if (scenes.size() < 3) GTEST_SKIP() << "shared data set cycles-starter not found beside the checkout";
  if (!python_has_skimage())
    GTEST_SKIP() << kPython << " cannot import numpy, skimage and OpenImageIO (apt-get install python3-skimage "
                 << "python3-openimageio)";
  const std::vector<fs::path> picked{scenes[0], scenes[1], scenes[2]};
  std::string cmd = std::string(kPython) + " " + quote(skimage_script().string());
  for (const fs::path& dir : picked)
    cmd += " " + quote((dir / "noisy_a.exr").string()) + " " + quote((dir / "reference.exr").string());
  std::string output;
  ASSERT_EQ(capture(cmd, output), 0) << cmd << "\n" << output;
  const nlohmann::json results = nlohmann::json::parse(output);
  ASSERT_EQ(results.size(), picked.size());
  double worst_ssim = 0, worst_rel = 0, worst_psnr = 0;
  for (size_t i = 0; i < picked.size(); ++i) {
    SCOPED_TRACE(picked[i].string());
    const nlohmann::json& e = results[i];
    const Image test = read_rgb(picked[i] / "noisy_a.exr");
    const Image ref = read_rgb(picked[i] / "reference.exr");
    Options tonemapped, linear;
    linear.ssim_space = SsimSpace::Linear;
    const Scores st = residue::metrics::compare(test, ref, tonemapped);
    const Scores sl = residue::metrics::compare(test, ref, linear);
    EXPECT_NEAR(st.ssim, e.at("ssim").get<double>(), 1e-5);
    EXPECT_NEAR(sl.ssim, e.at("ssim_linear").get<double>(), 1e-5);
    EXPECT_LT(rel_diff(st.mse, e.at("mse").get<double>()), 1e-9);
    EXPECT_LT(rel_diff(st.relmse, e.at("relmse").get<double>()), 1e-9);
    EXPECT_NEAR(st.psnr, e.at("psnr").get<double>(), 1e-6);
    EXPECT_NEAR(sl.psnr, e.at("psnr_linear").get<double>(), 1e-6);
    worst_ssim = std::max({worst_ssim, std::abs(st.ssim - e.at("ssim").get<double>()),
                           std::abs(sl.ssim - e.at("ssim_linear").get<double>())});
    worst_rel = std::max({worst_rel, rel_diff(st.mse, e.at("mse").get<double>()),
                          rel_diff(st.relmse, e.at("relmse").get<double>())});
    worst_psnr = std::max({worst_psnr, std::abs(st.psnr - e.at("psnr").get<double>()),
                           std::abs(sl.psnr - e.at("psnr_linear").get<double>())});
  }
  std::printf("[ metrics  ] vs scikit-image: worst |dSSIM| %.3g, worst relative MSE/relMSE %.3g, worst |dPSNR| "
              "%.3g dB\n",
              worst_ssim, worst_rel, worst_psnr);
}

void expect_matches_expected(const nlohmann::json& e, double ssim_tol, double rel_tol, double psnr_tol) {
  const auto [test, ref] = synthetic_pair(e.at("width").get<int64_t>(), e.at("height").get<int64_t>());
  Options tonemapped, linear;
  tonemapped.eps = linear.eps = e.at("eps").get<double>();
  linear.ssim_space = SsimSpace::Linear;
  const Scores st = residue::metrics::compare(test, ref, tonemapped);
  const Scores sl = residue::metrics::compare(test, ref, linear);
  EXPECT_NEAR(st.ssim, e.at("ssim").get<double>(), ssim_tol);
  EXPECT_NEAR(sl.ssim, e.at("ssim_linear").get<double>(), ssim_tol);
  EXPECT_LT(rel_diff(st.mse, e.at("mse").get<double>()), rel_tol);
  EXPECT_LT(rel_diff(st.relmse, e.at("relmse").get<double>()), rel_tol);
  EXPECT_NEAR(st.psnr, e.at("psnr").get<double>(), psnr_tol);
  EXPECT_NEAR(sl.psnr, e.at("psnr_linear").get<double>(), psnr_tol);
}

// Values computed once by skimage_metrics.py --synthetic and stored: a fixed reference without Python.
TEST(MetricsFixture, SyntheticPairMatchesStoredScikitImageValues) {
  const nlohmann::json e = read_json(fs::path(RESIDUE_TEST_FIXTURES) / "metrics_expected.json");
  expect_matches_expected(e, 1e-10, 1e-12, 1e-9);
}

// The stored fixture is what the script computes today (catches a stale fixture or a generator drift).
TEST(MetricsSkimage, StoredFixtureIsWhatTheScriptComputes) {
  if (!python_has_skimage()) GTEST_SKIP() << kPython << " cannot import numpy, skimage and OpenImageIO";
  const nlohmann::json stored = read_json(fs::path(RESIDUE_TEST_FIXTURES) / "metrics_expected.json");
  std::string output;
  const std::string cmd = std::string(kPython) + " " + quote(skimage_script().string()) + " --synthetic " +
                          std::to_string(stored.at("width").get<int64_t>()) + " " +
                          std::to_string(stored.at("height").get<int64_t>());
  ASSERT_EQ(capture(cmd, output), 0) << cmd << "\n" << output;
  const nlohmann::json live = nlohmann::json::parse(output);
  for (const char* key : {"mse", "relmse", "ssim", "psnr", "ssim_linear", "psnr_linear"})
    EXPECT_NEAR(live.at(key).get<double>(), stored.at(key).get<double>(), 1e-12) << key;
  // A different size through the live script too, to cover the generator beyond the stored case.
  output.clear();
  ASSERT_EQ(capture(std::string(kPython) + " " + quote(skimage_script().string()) + " --synthetic 47 12", output), 0);
  expect_matches_expected(nlohmann::json::parse(output), 1e-10, 1e-12, 1e-9);
}

// ---------------------------------------------------------------------------------------------------------
// 4. Non-finite values
// ---------------------------------------------------------------------------------------------------------

TEST(MetricsNonFinite, ExcludedPixelsAreDroppedCountedAndNaNInMaps) {
  const Image ref0 = residue::testing::random_image(40, 33, 3, 41, 0.0f, 3.0f);
  Image test = noisy(ref0, 42, 0.3f);
  Image ref = ref0;
  test.at(3, 4, 1) = kNaNf;     // test only
  test.at(20, 10, 0) = kInff;   // test only
  ref.at(30, 20, 2) = -kInff;   // reference only
  ref.at(0, 0, 0) = kNaNf;      // reference only, corner
  test.at(10, 25, 2) = kNaNf;   // both: counts as reference
  ref.at(10, 25, 1) = kInff;
  const std::vector<std::pair<int64_t, int64_t>> bad{{3, 4}, {20, 10}, {30, 20}, {0, 0}, {10, 25}};

  for (SsimSpace space : {SsimSpace::Tonemapped, SsimSpace::Linear}) {
    Options o;
    o.ssim_space = space;
    const Scores s = residue::metrics::compare(test, ref, o);
    EXPECT_EQ(s.excluded_reference, 3);
    EXPECT_EQ(s.excluded_test, 2);
    EXPECT_EQ(s.pixels, 40 * 33 - 5);
    const NaivePoint n = naive_point(test, ref, o);
    EXPECT_EQ(n.pixels, s.pixels);
    EXPECT_LT(rel_diff(s.mse, n.mse), 1e-12);
    EXPECT_LT(rel_diff(s.relmse, n.relmse), 1e-12);
    EXPECT_NEAR(s.psnr, n.psnr, 1e-9);
    ASSERT_TRUE(std::isfinite(s.ssim));
    const std::vector<double> naive = naive_ssim_map(test, ref, space);
    EXPECT_NEAR(s.ssim, naive_ssim_score(naive, 40, 33, test.bounds()), 1e-9);
  }
  for (MapKind kind : {MapKind::AbsoluteError, MapKind::SquaredError, MapKind::RelativeSquaredError, MapKind::Ssim,
                       MapKind::SignedDifference}) {
    SCOPED_TRACE(residue::metrics::to_string(kind));
    const Image map = residue::metrics::error_map(test, ref, kind);
    for (int64_t y = 0; y < 33; ++y)
      for (int64_t x = 0; x < 40; ++x) {
        const bool is_bad = std::find(bad.begin(), bad.end(), std::pair{x, y}) != bad.end();
        if (is_bad) EXPECT_TRUE(std::isnan(map.at(x, y))) << x << "," << y;
        else EXPECT_TRUE(std::isfinite(map.at(x, y))) << x << "," << y;
      }
  }
}

TEST(MetricsNonFinite, FirefliesGiveFiniteScores) {
  const Image ref0 = residue::testing::random_image(24, 20, 3, 51, 0.0f, 1.0f);
  for (float firefly : {1e6f, FLT_MAX}) {
    Image test = noisy(ref0, 52, 0.1f);
    Image ref = ref0;
    test.at(12, 10, 0) = firefly;
    test.at(2, 2, 1) = firefly;
    ref.at(7, 15, 2) = firefly;
    for (SsimSpace space : {SsimSpace::Tonemapped, SsimSpace::Linear}) {
      SCOPED_TRACE(std::to_string(firefly) + (space == SsimSpace::Linear ? " linear" : " tonemapped"));
      Options o;
      o.ssim_space = space;
      const Scores s = residue::metrics::compare(test, ref, o);
      EXPECT_EQ(s.pixels, 24 * 20);
      EXPECT_TRUE(std::isfinite(s.mse));
      EXPECT_TRUE(std::isfinite(s.relmse));
      EXPECT_TRUE(std::isfinite(s.psnr));
      EXPECT_TRUE(std::isfinite(s.ssim));
      EXPECT_GE(s.ssim, -1.0);
      EXPECT_LE(s.ssim, 1.0);
      EXPECT_LT(rel_diff(s.relmse, naive_point(test, ref, o).relmse), 1e-12);
      for (MapKind kind : {MapKind::SquaredError, MapKind::RelativeSquaredError, MapKind::Ssim}) {
        const Image map = residue::metrics::error_map(test, ref, kind, o);
        for (size_t i = 0; i < map.size(); ++i)
          if (kind == MapKind::Ssim) ASSERT_TRUE(std::isfinite(map.data()[i])) << i;
          else ASSERT_FALSE(std::isnan(map.data()[i])) << i;  // FLT_MAX^2 overflows float: inf, never NaN
      }
    }
  }
}

TEST(MetricsNonFinite, EverythingExcludedGivesNaNScoresAndCounts) {
  const Image ref(9, 8, 3, kNaNf);
  const Image test(9, 8, 3, 1.0f);
  const Scores s = residue::metrics::compare(test, ref);
  EXPECT_EQ(s.pixels, 0);
  EXPECT_EQ(s.excluded_reference, 72);
  EXPECT_EQ(s.excluded_test, 0);
  EXPECT_TRUE(std::isnan(s.mse) && std::isnan(s.relmse) && std::isnan(s.psnr) && std::isnan(s.ssim));
}

TEST(MetricsEdge, AllBlackReference) {
  const Image black(20, 16, 3, 0.0f);
  const Scores same = residue::metrics::compare(black, black);
  EXPECT_EQ(same.mse, 0.0);
  EXPECT_EQ(same.relmse, 0.0);
  EXPECT_EQ(same.psnr, kInf);
  EXPECT_NEAR(same.ssim, 1.0, 1e-12);
  const Image test = residue::testing::random_image(20, 16, 3, 61, 0.0f, 0.5f);
  const Scores s = residue::metrics::compare(test, black);
  ASSERT_TRUE(std::isfinite(s.relmse));
  EXPECT_LT(rel_diff(s.relmse, naive_point(test, black, Options{}).relmse), 1e-12);
  EXPECT_TRUE(std::isfinite(s.ssim));
}

TEST(MetricsEdge, IdenticalImages) {
  const Image im = residue::testing::random_image(33, 21, 3, 71, 0.0f, 20.0f);
  for (SsimSpace space : {SsimSpace::Tonemapped, SsimSpace::Linear}) {
    Options o;
    o.ssim_space = space;
    const Scores s = residue::metrics::compare(im, im, o);
    EXPECT_NEAR(s.ssim, 1.0, 1e-12);
    EXPECT_EQ(s.mse, 0.0);
    EXPECT_EQ(s.relmse, 0.0);
    EXPECT_EQ(s.psnr, kInf);
  }
}

// ---------------------------------------------------------------------------------------------------------
// 5. Regions of interest and errors
// ---------------------------------------------------------------------------------------------------------

double map_mean(const Image& map, const Rect& roi, bool interior_only, int64_t w, int64_t h) {
  double sum = 0;
  int64_t n = 0;
  for (int64_t y = 0; y < map.height(); ++y)
    for (int64_t x = 0; x < map.width(); ++x) {
      const int64_t ix = roi.x + x, iy = roi.y + y;
      if (interior_only && (ix < 5 || iy < 5 || ix >= w - 5 || iy >= h - 5)) continue;
      sum += map.at(x, y);
      ++n;
    }
  return sum / static_cast<double>(n);
}

TEST(MetricsRoi, ScoresAreMeansOfTheMapsOverTheRoi) {
  const Image ref = residue::testing::random_image(40, 33, 3, 81, 0.0f, 3.0f);
  const Image test = noisy(ref, 82, 0.4f);
  const std::vector<double> naive = naive_ssim_map(test, ref, SsimSpace::Tonemapped);
  // One reaching the image border (some interior pixels), one in a corner (none: all pixels count).
  for (const Rect roi : {Rect{7, 3, 33, 17}, Rect{0, 0, 4, 4}, Rect{36, 29, 4, 4}}) {
    SCOPED_TRACE(roi.to_string());
    Options o;
    o.roi = roi;
    const Scores s = residue::metrics::compare(test, ref, o);
    EXPECT_EQ(s.pixels, roi.area());
    const Image se = residue::metrics::error_map(test, ref, MapKind::SquaredError, o);
    const Image rse = residue::metrics::error_map(test, ref, MapKind::RelativeSquaredError, o);
    const Image ssim = residue::metrics::error_map(test, ref, MapKind::Ssim, o);
    ASSERT_EQ(ssim.width(), roi.width);
    ASSERT_EQ(ssim.height(), roi.height);
    EXPECT_LT(rel_diff(s.mse, map_mean(se, roi, false, 40, 33)), 1e-6);
    EXPECT_LT(rel_diff(s.relmse, map_mean(rse, roi, false, 40, 33)), 1e-6);
    const bool has_interior = roi.x + roi.width > 5 && roi.y + roi.height > 5 && roi.x < 35 && roi.y < 28;
    EXPECT_NEAR(s.ssim, map_mean(ssim, roi, has_interior, 40, 33), 1e-6);
    EXPECT_NEAR(s.ssim, naive_ssim_score(naive, 40, 33, roi), 1e-12);
    EXPECT_LT(rel_diff(s.relmse, naive_point(test, ref, o).relmse), 1e-12);
    // The windows reach outside the ROI into the image: the map is the whole image's, cropped.
    for (int64_t y = 0; y < roi.height; ++y)
      for (int64_t x = 0; x < roi.width; ++x)
        ASSERT_NEAR(ssim.at(x, y), naive[static_cast<size_t>((roi.y + y) * 40 + roi.x + x)], 1e-6);
  }
}

TEST(MetricsRoi, WholeImageRoiEqualsNoRoi) {
  const Image ref = residue::testing::random_image(70, 45, 3, 91, 0.0f, 2.0f);
  Image test = noisy(ref, 92, 0.3f);
  test.at(5, 5, 0) = kNaNf;
  Options whole;
  whole.roi = ref.bounds();
  expect_bitwise_equal(residue::metrics::compare(test, ref, whole), residue::metrics::compare(test, ref));
  const Image a = residue::metrics::error_map(test, ref, MapKind::Ssim, whole);
  const Image b = residue::metrics::error_map(test, ref, MapKind::Ssim);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(float)));
}

// Runs f, expecting a residue::Error of kind Usage whose message contains every one of `needles`.
template <class F>
void expect_usage_error(F&& f, const std::vector<std::string>& needles) {
  try {
    f();
    ADD_FAILURE() << "no error thrown";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Usage) << e.what();
    for (const std::string& needle : needles)
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << needle << " not in: " << e.what();
  }
}

TEST(MetricsRoi, BadArgumentsThrowUsageErrors) {
  const Image a = residue::testing::random_image(40, 33, 3, 1);
  const Image b = residue::testing::random_image(41, 33, 3, 2);
  expect_usage_error([&] { residue::metrics::compare(a, b); }, {"40x33", "41x33"});
  expect_usage_error([&] { residue::metrics::error_map(a, b, MapKind::Ssim); }, {"40x33", "41x33"});
  for (const Rect roi : {Rect{30, 0, 11, 5}, Rect{-1, 0, 5, 5}, Rect{0, 30, 5, 4}, Rect{3, 3, 0, 5}}) {
    SCOPED_TRACE(roi.to_string());
    Options o;
    o.roi = roi;
    expect_usage_error([&] { residue::metrics::compare(a, a, o); }, {roi.to_string()});
    expect_usage_error([&] { residue::metrics::error_map(a, a, MapKind::RelativeSquaredError, o); },
                       {roi.to_string()});
  }
  const Image two(40, 33, 2, 0.5f);
  expect_usage_error([&] { residue::metrics::compare(two, two); }, {"2 channel", "at least 3"});
  Options bad_eps;
  bad_eps.eps = 0;
  expect_usage_error([&] { residue::metrics::compare(a, a, bad_eps); }, {"eps"});
}

// ---------------------------------------------------------------------------------------------------------
// 6. Tiny images
// ---------------------------------------------------------------------------------------------------------

TEST(MetricsSmall, TinyImagesAndRois) {
  for (auto [w, h] : {std::pair<int64_t, int64_t>{1, 1}, {7, 13}, {13, 7}, {11, 11}, {12, 3}}) {
    SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
    const Image ref = residue::testing::random_image(w, h, 3, 101, 0.0f, 2.0f);
    const Image test = noisy(ref, 102, 0.5f);
    const std::vector<double> naive = naive_ssim_map(test, ref, SsimSpace::Tonemapped);
    std::vector<Rect> rois{ref.bounds(), Rect{w - 1, h - 1, 1, 1}, Rect{0, h / 2, w, h - h / 2}};
    for (const Rect& roi : rois) {
      SCOPED_TRACE(roi.to_string());
      Options o;
      o.roi = roi;
      const Scores s = residue::metrics::compare(test, ref, o);
      ASSERT_TRUE(std::isfinite(s.ssim));
      EXPECT_GE(s.ssim, -1.0);
      EXPECT_LE(s.ssim, 1.0);
      EXPECT_NEAR(s.ssim, naive_ssim_score(naive, w, h, roi), 1e-12);
      EXPECT_LT(rel_diff(s.relmse, naive_point(test, ref, o).relmse), 1e-12);
      const Image map = residue::metrics::error_map(test, ref, MapKind::Ssim, o);
      ASSERT_EQ(map.pixel_count(), roi.area());
      for (size_t i = 0; i < map.size(); ++i) ASSERT_TRUE(std::isfinite(map.data()[i]));
    }
  }
}

// ---------------------------------------------------------------------------------------------------------
// 7. Determinism
// ---------------------------------------------------------------------------------------------------------

TEST(MetricsDeterminism, BitIdenticalAcrossRunsAndThreadCounts) {
  const Image ref = residue::testing::random_image(700, 200, 3, 111, 0.0f, 5.0f);
  Image test = noisy(ref, 112, 1.0f);
  test.at(600, 100, 2) = kNaNf;
  const Scores first = residue::metrics::compare(test, ref);
  const Scores second = residue::metrics::compare(test, ref);
  expect_bitwise_equal(first, second);
  Scores serial;
  Image serial_map;
  tbb::task_arena one(1);
  one.execute([&] {
    serial = residue::metrics::compare(test, ref);
    serial_map = residue::metrics::error_map(test, ref, MapKind::Ssim);
  });
  expect_bitwise_equal(first, serial);
  const Image map = residue::metrics::error_map(test, ref, MapKind::Ssim);
  ASSERT_EQ(map.size(), serial_map.size());
  for (size_t i = 0; i < map.size(); ++i) {
    const float a = map.data()[i], b = serial_map.data()[i];
    ASSERT_TRUE((std::isnan(a) && std::isnan(b)) || a == b) << i;
  }
}

// ---------------------------------------------------------------------------------------------------------
// 8. Tonemap
// ---------------------------------------------------------------------------------------------------------

TEST(MetricsTonemap, KnownValuesAndLimits) {
  using residue::tonemap_filmic_srgb;
  using residue::tonemap_filmic_srgb_f64;
  EXPECT_EQ(tonemap_filmic_srgb(0.0f), 0.0f);
  EXPECT_NEAR(tonemap_filmic_srgb(11.2f), 1.0f, 1e-6);
  EXPECT_NEAR(tonemap_filmic_srgb_f64(11.2), 1.0, 1e-12);
  EXPECT_EQ(tonemap_filmic_srgb(kNaNf), 0.0f);
  EXPECT_EQ(tonemap_filmic_srgb(kInff), 1.0f);
  EXPECT_EQ(tonemap_filmic_srgb(-kInff), 0.0f);
  EXPECT_EQ(tonemap_filmic_srgb(-3.0f), 0.0f);
  EXPECT_EQ(tonemap_filmic_srgb(FLT_MAX), 1.0f);
  EXPECT_EQ(tonemap_filmic_srgb(1e30f), 1.0f);
  // Constants computed with float64 NumPy (tonemap() of tests/reference/skimage_metrics.py).
  const std::vector<std::pair<double, double>> known{{0.0005, 0.0024747347818375094},
                                                     {0.001, 0.0049496233070692435},
                                                     {0.18, 0.2873050835125842},
                                                     {1.0, 0.5876313974474693},
                                                     {4.0, 0.8614318190115159},
                                                     {11.0, 0.9982213392129883}};
  for (auto [x, y] : known) {
    EXPECT_NEAR(tonemap_filmic_srgb_f64(x), y, 1e-14) << x;
    EXPECT_NEAR(tonemap_filmic_srgb(static_cast<float>(x)), y, 1e-6) << x;
  }
  // Hand check of 1.0: f(1) = 0.204 / 0.71 - 1/15, f(11.2) = 19.38 / 24.476 - 1/15.
  const double t = (0.204 / 0.71 - 1.0 / 15) / (19.38 / 24.476 - 1.0 / 15);
  EXPECT_NEAR(tonemap_filmic_srgb_f64(1.0), 1.055 * std::pow(t, 1 / 2.4) - 0.055, 1e-12);
  float previous = -1;
  for (int i = 0; i <= 4000; ++i) {
    const double x = i * 0.005;
    const float y = tonemap_filmic_srgb(static_cast<float>(x));
    EXPECT_GE(y, previous) << x;
    EXPECT_LE(y, 1.0f);
    EXPECT_NEAR(tonemap_filmic_srgb_f64(x), naive_tonemap(x), 1e-12) << x;
    previous = y;
  }
  EXPECT_FLOAT_EQ(residue::srgb_oetf(0.5f), 0.7353569830524495f);
  EXPECT_FLOAT_EQ(residue::srgb_oetf(0.001f), 0.01292f);
  EXPECT_EQ(residue::srgb_oetf(2.0f), 1.0f);
  EXPECT_EQ(residue::srgb_oetf(-1.0f), 0.0f);
  EXPECT_EQ(residue::srgb_oetf(kNaNf), 0.0f);
}

// ---------------------------------------------------------------------------------------------------------
// Names and the formula paragraph
// ---------------------------------------------------------------------------------------------------------

TEST(MetricsMapKind, NamesRoundTrip) {
  for (MapKind kind : {MapKind::AbsoluteError, MapKind::SquaredError, MapKind::RelativeSquaredError, MapKind::Ssim})
    EXPECT_EQ(residue::metrics::map_kind_from_string(residue::metrics::to_string(kind)), kind);
  EXPECT_STREQ(residue::metrics::to_string(MapKind::AbsoluteError), "abs");
  EXPECT_STREQ(residue::metrics::to_string(MapKind::SquaredError), "se");
  EXPECT_STREQ(residue::metrics::to_string(MapKind::RelativeSquaredError), "rse");
  EXPECT_STREQ(residue::metrics::to_string(MapKind::Ssim), "ssim");
  EXPECT_FALSE(residue::metrics::map_kind_from_string("mse").has_value());
  EXPECT_FALSE(residue::metrics::map_kind_from_string("").has_value());
}

TEST(MetricsFormula, StatesEpsAndSpace) {
  Options o;
  o.eps = 0.05;
  const std::string text = residue::metrics::formula_text(o);
  EXPECT_NE(text.find("eps = 0.05"), std::string::npos) << text;
  EXPECT_NE(text.find("(r^2 + eps)"), std::string::npos) << text;
  EXPECT_NE(text.find("tonemapped"), std::string::npos) << text;
  EXPECT_NE(text.find("11.2"), std::string::npos) << text;
  EXPECT_EQ(text.find('\n'), std::string::npos) << "one paragraph";
  o.ssim_space = SsimSpace::Linear;
  const std::string linear = residue::metrics::formula_text(o);
  EXPECT_NE(linear.find("on linear values"), std::string::npos) << linear;
  EXPECT_EQ(linear.find("Hable"), std::string::npos) << linear;
}

}  // namespace

namespace residue {
namespace {

// The rows [y0, y1) of `img` widened by SSIM's halo, as a band reader would hand them over.
Image band_rows(const Image& img, int64_t y0, int64_t y1, int64_t* rows_y0) {
  *rows_y0 = std::max<int64_t>(0, y0 - metrics::ScoreAccumulator::kHalo);
  const int64_t end = std::min(img.height(), y1 + metrics::ScoreAccumulator::kHalo);
  return crop(img, {0, *rows_y0, img.width(), end - *rows_y0});
}

metrics::Scores banded(const Image& test, const Image& ref, const metrics::Options& o, int64_t band) {
  metrics::ScoreAccumulator acc(test.width(), test.height(), o);
  const Rect region = acc.region();
  for (int64_t y0 = region.y; y0 < region.y + region.height; y0 += band) {
    const int64_t y1 = std::min(y0 + band, region.y + region.height);
    int64_t t0 = 0, r0 = 0;
    const Image t = band_rows(test, y0, y1, &t0), r = band_rows(ref, y0, y1, &r0);
    acc.add(t, r, t0, y0, y1);
  }
  return acc.scores();
}

// Band by band gives compare()'s scores bit for bit (the same tiles summed in the same order), with NaN and Inf
// excluded, an ROI, and heights that are and are not multiples of the band.
TEST(MetricsBanded, EqualsWholeImageBitForBit) {
  for (const auto& [w, h] : std::vector<std::pair<int64_t, int64_t>>{{300, 200}, {97, 128}, {40, 7}}) {
    Image test = testing::random_image(w, h, 3, 11, 0.0f, 2.0f);
    const Image ref = testing::random_image(w, h, 4, 12, 0.0f, 2.0f);
    test.at(w / 2, h / 2, 1) = std::numeric_limits<float>::quiet_NaN();
    test.at(1, h - 1, 0) = std::numeric_limits<float>::infinity();
    for (const std::optional<Rect>& roi : {std::optional<Rect>(), std::optional<Rect>(Rect{3, 2, w / 2, h - 3})}) {
      metrics::Options o;
      o.roi = roi;
      const metrics::Scores whole = metrics::compare(test, ref, o);
      for (int64_t band : {64, 128, 256}) {
        SCOPED_TRACE(::testing::Message() << w << "x" << h << " band " << band << (roi ? " roi" : ""));
        const metrics::Scores b = banded(test, ref, o, band);
        EXPECT_EQ(b.relmse, whole.relmse);
        EXPECT_EQ(b.ssim, whole.ssim);
        EXPECT_EQ(b.psnr, whole.psnr);
        EXPECT_EQ(b.mse, whole.mse);
        EXPECT_EQ(b.pixels, whole.pixels);
        EXPECT_EQ(b.excluded_test, whole.excluded_test);
      }
    }
  }
}

TEST(MetricsBanded, RefusesBandsOutOfOrderOrWithoutTheirHalo) {
  const Image img = testing::random_image(50, 200, 3, 1);
  metrics::ScoreAccumulator acc(50, 200);
  int64_t r0 = 0;
  const Image b = band_rows(img, 0, 64, &r0);
  EXPECT_THROW(acc.add(b, b, r0, 64, 128), Error);         // not from the top
  EXPECT_THROW(acc.add(b, b, r0, 0, 60), Error);           // not a multiple of 64
  const Image short_band = crop(img, {0, 0, 50, 64});      // no rows below for SSIM's window
  EXPECT_THROW(acc.add(short_band, short_band, 0, 0, 64), Error);
  acc.add(b, b, r0, 0, 64);
  EXPECT_THROW(acc.scores(), Error);                       // rows 64-200 never added
}

}  // namespace
}  // namespace residue
