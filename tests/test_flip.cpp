// FLIP (core/metrics/flip.h) against NVIDIA's reference implementation: the means, exposure ranges and per-pixel
// maps its code produced for real and synthetic pairs (../shared/reference/flip, see FLIP.md section 11), within
// the tolerances suggested there; and the properties any FLIP has (identical images 0, a shift costs more than
// none, excluded pixels counted).
#include <cmath>
#include <fstream>
#include <string>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/metrics/flip.h"
#include "core/util/error.h"

namespace residue {
namespace {

namespace fs = std::filesystem;

fs::path flip_dir() { return fs::path(RESIDUE_SHARED_DIR) / "reference" / "flip"; }

#define REQUIRE_FLIP_REFERENCE()                                                            \
  do {                                                                                      \
    if (!fs::exists(flip_dir() / "expected.json")) GTEST_SKIP() << "no " << flip_dir(); \
  } while (0)

// An image as stored (OpenImageIO, independent of core's loader): an EXR's float values; a PNG's 8-bit codes
// decoded with the sRGB EOTF as FLIP's tool decodes them (code / 255, threshold 0.04045).
Image read(const fs::path& path) {
  auto in = OIIO::ImageInput::open(path.string());
  EXPECT_TRUE(in) << path;
  if (!in) return {};
  const OIIO::ImageSpec& spec = in->spec();
  Image img(spec.width, spec.height, 3);
  const bool png = path.extension() == ".png";
  std::vector<float> floats(static_cast<size_t>(spec.width * spec.height * spec.nchannels));
  std::vector<unsigned char> codes(floats.size());
  if (png) EXPECT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, codes.data()));
  else EXPECT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, floats.data()));
  for (int64_t y = 0; y < spec.height; ++y)
    for (int64_t x = 0; x < spec.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const size_t i = static_cast<size_t>((y * spec.width + x) * spec.nchannels + std::min(c, spec.nchannels - 1));
        if (!png) {
          img.at(x, y, c) = floats[i];
          continue;
        }
        const double v = static_cast<float>(codes[i]) / 255.0f;
        img.at(x, y, c) = static_cast<float>(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
      }
  return img;
}

nlohmann::json expected() {
  std::ifstream in(flip_dir() / "expected.json");
  return nlohmann::json::parse(in);
}

double max_abs_diff(const Image& a, const Image& b) {
  double worst = 0;
  for (int64_t y = 0; y < a.height(); ++y)
    for (int64_t x = 0; x < a.width(); ++x) worst = std::max(worst, std::abs(double(a.at(x, y, 0)) - b.at(x, y, 0)));
  return worst;
}

TEST(Flip, MeansAndExposuresAreTheReferenceImplementations) {
  REQUIRE_FLIP_REFERENCE();
  const nlohmann::json all = expected();
  ASSERT_EQ(all["pairs"].size(), 6u);
  for (const auto& pair : all["pairs"]) {
    const std::string id = pair["id"];
    SCOPED_TRACE(id);
    const Image ref = read(flip_dir() / pair["reference_exr"].get<std::string>());
    const Image test = read(flip_dir() / pair["test_exr"].get<std::string>());
    const metrics::FlipResult hdr = metrics::hdr_flip(test, ref);
    EXPECT_NEAR(hdr.mean, pair["hdr_flip_mean"].get<double>(), 1e-5);
    EXPECT_NEAR(hdr.exposures.start, pair["start_exposure"].get<double>(), 1e-5);
    EXPECT_NEAR(hdr.exposures.stop, pair["stop_exposure"].get<double>(), 1e-5);
    EXPECT_EQ(hdr.exposures.count, pair["num_exposures"].get<int>());
    EXPECT_EQ(hdr.pixels, ref.width() * ref.height());
    const metrics::FlipResult ldr = metrics::ldr_flip(read(flip_dir() / pair["test_png"].get<std::string>()),
                                                      read(flip_dir() / pair["reference_png"].get<std::string>()));
    EXPECT_NEAR(ldr.mean, pair["ldr_flip_mean"].get<double>(), 1e-5);
    std::printf("[ measured ] %-22s HDR-FLIP %.7f (reference code %.7f), LDR-FLIP %.7f (%.7f)\n", id.c_str(),
                hdr.mean, pair["hdr_flip_mean"].get<double>(), ldr.mean, pair["ldr_flip_mean"].get<double>());
  }
}

// Two subtle mistakes (67 ppd instead of 67.02; the Cz kernel's two terms normalised apart) show only in the maps.
TEST(Flip, MapsAreTheReferenceImplementationsPixelByPixel) {
  REQUIRE_FLIP_REFERENCE();
  const struct {
    std::string name, reference, test;
  } cases[] = {{"cornell-box_nfor", "cornell-box/reference", "cornell-box/nfor"},
               {"tiny13x7", "synthetic/tiny13x7_reference", "synthetic/tiny13x7_test"},
               {"small61x37", "synthetic/small61x37_reference", "synthetic/small61x37_test"}};
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const fs::path in = flip_dir() / "inputs";
    const metrics::FlipResult hdr = metrics::hdr_flip(read(in / (c.test + ".exr")), read(in / (c.reference + ".exr")));
    const Image hdr_map = read(flip_dir() / "maps" / (c.name + "_hdrflip.exr"));
    const double hdr_worst = max_abs_diff(hdr.map, hdr_map);
    EXPECT_LE(hdr_worst, 1e-4);
    const metrics::FlipResult ldr = metrics::ldr_flip(read(in / (c.test + ".png")), read(in / (c.reference + ".png")));
    const double ldr_worst = max_abs_diff(ldr.map, read(flip_dir() / "maps" / (c.name + "_ldrflip.exr")));
    EXPECT_LE(ldr_worst, 1e-4);
    // The exposure that gave each pixel its error: the same one, but where two exposures tie to rounding.
    const Image exposure = read(flip_dir() / "maps" / (c.name + "_hdrflip_exposure.exr"));
    int64_t same = 0, counted = 0;
    for (int64_t y = 0; y < exposure.height(); ++y)
      for (int64_t x = 0; x < exposure.width(); ++x) {
        if (hdr_map.at(x, y, 0) <= 0) continue;  // never written by the reference code
        ++counted;
        same += std::abs(exposure.at(x, y, 0) - hdr.exposure_map.at(x, y, 0)) < 1e-6;
      }
    EXPECT_GE(same, counted * 999 / 1000) << same << " of " << counted;
    std::printf("[ measured ] %-18s largest difference per pixel: HDR-FLIP %.2e, LDR-FLIP %.2e; exposure %lld of %lld\n",
                c.name.c_str(), hdr_worst, ldr_worst, static_cast<long long>(same), static_cast<long long>(counted));
  }
}

TEST(Flip, IdenticalIsZeroAShiftCostsAndExcludedPixelsAreCounted) {
  REQUIRE_FLIP_REFERENCE();
  const Image ref = read(flip_dir() / "inputs" / "cornell-box" / "reference.exr");
  EXPECT_EQ(metrics::hdr_flip(ref, ref).mean, 0.0);
  EXPECT_EQ(metrics::ldr_flip(ref, ref).mean, 0.0);
  // Shifted right by one pixel, the first column replicated: the reference code's 0.0643595 (expected.json).
  Image shifted = ref;
  for (int64_t y = 0; y < ref.height(); ++y)
    for (int64_t x = 0; x < ref.width(); ++x)
      for (int c = 0; c < 3; ++c) shifted.at(x, y, c) = ref.at(std::max<int64_t>(0, x - 1), y, c);
  const auto sanity = expected()["sanity"]["cornell-box"]["shift1px"];
  EXPECT_NEAR(metrics::hdr_flip(shifted, ref).mean, sanity["hdr"].get<double>(), 1e-5);

  Image holed = shifted;
  holed.at(5, 7, 1) = std::numeric_limits<float>::quiet_NaN();
  holed.at(100, 9, 0) = std::numeric_limits<float>::infinity();
  const metrics::FlipResult r = metrics::hdr_flip(holed, ref);
  EXPECT_EQ(r.excluded, 2);
  EXPECT_EQ(r.pixels, ref.width() * ref.height() - 2);
  EXPECT_TRUE(std::isnan(r.map.at(5, 7, 0)));
  EXPECT_TRUE(std::isfinite(r.mean));
  EXPECT_THROW(metrics::hdr_flip(Image(4, 4, 3), Image(4, 5, 3)), Error);
  EXPECT_THROW(metrics::hdr_flip(Image(4, 4, 3, 0.0f), Image(4, 4, 3, 0.0f)), Error) << "an all-black reference has no exposures";
  metrics::FlipOptions given;
  given.start_exposure = -1.0;
  given.stop_exposure = 2.0;
  EXPECT_EQ(metrics::flip_exposures(Image(4, 4, 3, 0.0f), given).count, 3) << "given exposures need no statistics";
}

}  // namespace
}  // namespace residue
