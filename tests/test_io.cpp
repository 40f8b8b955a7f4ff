// Output files: atomic writing, EXR, colour-mapped maps, metrics reports. Real files, read back with OIIO.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <tuple>

#include "core/image/colormap.h"
#include "core/io/atomic_file.h"
#include "core/io/exr_writer.h"
#include "core/io/map_writer.h"
#include "core/io/metrics_report.h"
#include "core/io/provenance.h"
#include "core/util/error.h"
#include "support/test_support.h"

namespace residue {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

constexpr float kInf = std::numeric_limits<float>::infinity();
const float kNaN = std::numeric_limits<float>::quiet_NaN();

// --- helpers
// -------------------------------------------------------------------------------------------------

std::string read_bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

void write_bytes(const fs::path& p, const std::string& bytes) {
  std::ofstream f(p, std::ios::binary);
  f << bytes;
}

std::vector<std::string> folder_entries(const fs::path& folder) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(folder)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

struct ReadBack {
  OIIO::ImageSpec spec;
  std::vector<float> pixels;        // as float
  std::vector<uint16_t> half_bits;  // as stored, when the file is half
};

ReadBack read_image(const fs::path& p) {
  auto in = OIIO::ImageInput::open(p.string());
  if (!in) throw std::runtime_error("cannot open " + p.string() + ": " + OIIO::geterror());
  ReadBack r;
  r.spec = in->spec();
  const size_t n = r.spec.image_pixels() * static_cast<size_t>(r.spec.nchannels);
  r.pixels.resize(n);
  EXPECT_TRUE(in->read_image(0, 0, 0, -1, OIIO::TypeFloat, r.pixels.data())) << in->geterror();
  if (r.spec.format == OIIO::TypeHalf) {
    r.half_bits.resize(n);
    EXPECT_TRUE(in->read_image(0, 0, 0, -1, OIIO::TypeHalf, r.half_bits.data())) << in->geterror();
  }
  return r;
}

uint32_t bits(float v) {
  uint32_t b = 0;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

uint16_t oiio_half_bits(float v) {
  uint16_t h = 0;
  OIIO::convert_pixel_values(OIIO::TypeFloat, &v, OIIO::TypeHalf, &h, 1);
  return h;
}

// Random values with the awkward ones sprinkled in.
Image awkward_image(int64_t w, int64_t h, int channels, const std::vector<float>& specials) {
  Image img = testing::random_image(w, h, channels, 7, -4.0f, 4.0f);
  for (size_t i = 0; i < specials.size() && i < img.size(); ++i)
    img.data()[(i * 7) % img.size()] = specials[i];
  return img;
}

template <typename F>
ErrorKind error_kind_of(F&& f, std::string* message = nullptr) {
  try {
    f();
  } catch (const Error& e) {
    if (message) *message = e.what();
    return e.kind();
  }
  ADD_FAILURE() << "no residue::Error thrown";
  return ErrorKind::Usage;
}

const std::vector<std::pair<int64_t, int64_t>> kSizes = {{1, 1}, {7, 13}, {256, 3}};

// Writes `img` as EXR with the given pixel type and compression and reads it back.
ReadBack exr_round_trip(const TempDir& dir, const Image& img, io::PixelType type,
                        const std::string& compression) {
  const fs::path path = dir / ((type == io::PixelType::Half ? "h_" : "f_") + compression + "_" +
                               std::to_string(img.width()) + "x" + std::to_string(img.height()) + ".exr");
  io::ExrWriteOptions options;
  options.pixel_type = type;
  options.compression = compression;
  io::write_exr(path, img, options);
  ReadBack r = read_image(path);
  EXPECT_EQ(r.spec.width, img.width());
  EXPECT_EQ(r.spec.height, img.height());
  EXPECT_EQ(r.spec.nchannels, img.channels());
  EXPECT_EQ(r.spec.format, type == io::PixelType::Half ? OIIO::TypeHalf : OIIO::TypeFloat);
  EXPECT_EQ(r.spec.get_string_attribute("compression"), compression.substr(0, compression.find(':')));
  return r;
}

// --- EXR
// -----------------------------------------------------------------------------------------------------

TEST(IoExr, FloatRoundTripIsBitExact) {
  const std::vector<float> specials = {kNaN,
                                       kInf,
                                       -kInf,
                                       1e-40f,
                                       -1e-42f,
                                       1e30f,
                                       -3.5f,
                                       -0.0f,
                                       std::numeric_limits<float>::max(),
                                       std::numeric_limits<float>::min()};
  TempDir dir;
  for (const char* compression : {"none", "rle", "zips", "zip", "piz"})
    for (auto [w, h] : kSizes) {
      SCOPED_TRACE(std::string(compression) + " " + std::to_string(w) + "x" + std::to_string(h));
      const Image img = awkward_image(w, h, 3, specials);
      const ReadBack r = exr_round_trip(dir, img, io::PixelType::Float, compression);
      ASSERT_EQ(r.pixels.size(), img.size());
      for (size_t i = 0; i < img.size(); ++i)
        ASSERT_EQ(bits(r.pixels[i]), bits(img.data()[i])) << "index " << i;
    }
}

TEST(IoExr, HalfRoundTripMatchesHalfConversion) {
  // Exactly representable in half: read back as the same floats.
  const float smallest_normal = 6.103515625e-05f, smallest_denormal = 5.9604644775390625e-08f;
  const std::vector<float> exact = {0.5f,     1.0f,      -2.0f,           2048.0f,
                                    65504.0f, -65504.0f, smallest_normal, smallest_denormal,
                                    -0.0f,    kInf,      -kInf,           0.333251953125f};
  // Not representable: compared with OpenImageIO's own float -> half conversion, of the value clamped to the
  // half range for finite values beyond it (written as +-65504, not Inf).
  const std::vector<float> inexact = {0.1f, 1e30f, -1e30f, 1e-10f, 3.14159f, 70000.0f};
  TempDir dir;
  for (const char* compression : {"none", "rle", "zips", "zip", "piz", "pxr24"})
    for (auto [w, h] : kSizes) {
      SCOPED_TRACE(std::string(compression) + " " + std::to_string(w) + "x" + std::to_string(h));
      Image img = awkward_image(w, h, 4, inexact);
      for (size_t i = 0; i < exact.size() && i < img.size(); ++i) img.data()[img.size() - 1 - i] = exact[i];
      if (img.size() > exact.size() + inexact.size()) img.data()[img.size() / 2] = kNaN;
      const ReadBack r = exr_round_trip(dir, img, io::PixelType::Half, compression);
      ASSERT_EQ(r.half_bits.size(), img.size());
      for (size_t i = 0; i < img.size(); ++i) {
        const float v = img.data()[i];
        if (std::isnan(v)) {
          EXPECT_TRUE(std::isnan(r.pixels[i])) << "index " << i;
          continue;
        }
        const float fitted = std::isfinite(v) ? std::clamp(v, -65504.0f, 65504.0f) : v;
        ASSERT_EQ(r.half_bits[i], oiio_half_bits(fitted)) << "index " << i << " value " << v;
      }
      for (size_t i = 0; i < exact.size() && i < img.size(); ++i)
        EXPECT_EQ(bits(r.pixels[img.size() - 1 - i]), bits(exact[i])) << exact[i];
    }
}

// Finite values beyond the half range become +-65504, never Inf, and are counted; float output keeps them;
// NaN and Inf stay what they are (the denoiser is responsible for finite output).
TEST(IoExr, HalfOutputClampsFiniteValuesBeyondItsRange) {
  TempDir dir;
  Image img(4, 2, 3);
  const std::vector<float> v = {1e30f, -1e30f, 7e4f, 65504.0f, 1.5f, -3.0f, kInf, 0.0f, 1e5f, 2.0f, 3.0f, 4.0f,
                                5.0f,  6.0f,   7.0f, 8.0f,     9.0f, 10.f,  11.f, 12.f, 13.f, 14.f, 15.f, -7e4f};
  std::copy(v.begin(), v.end(), img.data());
  io::ExrWriteOptions o;
  const io::WriteReport half = io::write_exr(dir.path() / "h.exr", img, o);
  EXPECT_EQ(half.clamped_to_half, 5);  // 1e30, -1e30, 7e4, 1e5, -7e4
  const Image back = testing::read_exr_float(dir.path() / "h.exr");
  EXPECT_EQ(back.data()[0], 65504.0f);
  EXPECT_EQ(back.data()[1], -65504.0f);
  EXPECT_EQ(back.data()[2], 65504.0f);
  EXPECT_EQ(back.data()[23], -65504.0f);
  EXPECT_TRUE(std::isinf(back.data()[6]));
  o.pixel_type = io::PixelType::Float;
  EXPECT_EQ(io::write_exr(dir.path() / "f.exr", img, o).clamped_to_half, 0);
  EXPECT_EQ(testing::read_exr_float(dir.path() / "f.exr").data()[0], 1e30f);
  // Band by band, the same.
  o.pixel_type = io::PixelType::Half;
  const io::WriteReport bands = io::write_exr_bands(dir.path() / "b.exr", 4, 2, 3, 1, o, [&](int64_t y0, int64_t rows) {
    return crop(img, {0, y0, 4, rows});
  });
  EXPECT_EQ(bands.clamped_to_half, 5);
  EXPECT_EQ(testing::read_exr_float(dir.path() / "b.exr").data()[1], -65504.0f);
}

TEST(IoExr, LossyCompressionsWriteTheRightSize) {
  TempDir dir;
  for (const char* compression : {"dwaa", "dwab", "b44", "b44a", "pxr24", "dwaa:45"}) {
    SCOPED_TRACE(compression);
    const Image img = testing::random_image(37, 21, 3, 3);
    for (io::PixelType type : {io::PixelType::Half, io::PixelType::Float})
      EXPECT_EQ(exr_round_trip(dir, img, type, compression).pixels.size(), img.size());
  }
}

TEST(IoExr, UnknownCompressionNamesTheAllowedOnes) {
  TempDir dir;
  io::ExrWriteOptions options;
  options.compression = "zstd";
  std::string message;
  EXPECT_EQ(error_kind_of([&] { io::write_exr(dir / "x.exr", Image(2, 2, 3), options); }, &message),
            ErrorKind::Usage);
  for (const char* name : {"zstd", "none", "zip", "piz", "dwaa", "dwab", "b44a", "pxr24"})
    EXPECT_NE(message.find(name), std::string::npos) << message;
  options.compression = "zip:fast";
  EXPECT_EQ(error_kind_of([&] { io::write_exr(dir / "x.exr", Image(2, 2, 3), options); }), ErrorKind::Usage);
  EXPECT_TRUE(folder_entries(dir.path()).empty());
}

TEST(IoExr, EveryListedCompressionIsWritten) {
  TempDir dir;
  const auto list = io::exr_compressions();
  EXPECT_EQ(list.size(), size_t(10));
  for (const auto& c : list) {
    SCOPED_TRACE(c);
    EXPECT_EQ(exr_round_trip(dir, testing::random_image(9, 7, 3, 1), io::PixelType::Half, c).pixels.size(), size_t(9 * 7 * 3));
  }
}

TEST(IoProvenance, RecordsTheSetFieldsWithTheirTypes) {
  TempDir dir;
  io::ExrWriteOptions o;
  io::record(o.residue_attributes, {.model = "small", .backend = "onednn fp32", .written_by = "test",
                                    .seconds = 1.5f, .energy_correction = true, .variance_blend = false,
                                    .strength = 0.75f});
  io::write_exr(dir / "p.exr", Image(4, 4, 3), o);
  auto in = OIIO::ImageInput::open((dir / "p.exr").string());
  ASSERT_TRUE(in);
  const auto& spec = in->spec();
  EXPECT_EQ(spec.get_string_attribute("residue:model"), "small");
  EXPECT_EQ(spec.get_string_attribute("residue:backend"), "onednn fp32");
  EXPECT_EQ(spec.get_string_attribute("residue:written_by"), "test");
  EXPECT_EQ(spec.get_string_attribute("residue:version"), RESIDUE_VERSION);
  EXPECT_EQ(spec.find_attribute("residue:time_s")->type(), OIIO::TypeFloat);
  EXPECT_EQ(spec.get_float_attribute("residue:time_s"), 1.5f);
  EXPECT_EQ(spec.get_int_attribute("residue:energy_correction", -1), 1);
  EXPECT_EQ(spec.get_int_attribute("residue:variance_blend", -1), 0);
  EXPECT_EQ(spec.get_float_attribute("residue:strength"), 0.75f);
  // What was not set is not written.
  EXPECT_EQ(spec.find_attribute("residue:architecture"), nullptr);
  EXPECT_EQ(spec.find_attribute("residue:source"), nullptr);
  EXPECT_EQ(spec.find_attribute("residue:result"), nullptr);
}

TEST(IoExr, ChannelNames) {
  TempDir dir;
  const std::vector<std::pair<int, std::vector<std::string>>> defaults = {
      {1, {"Y"}},
      {2, {"C0", "C1"}},
      {3, {"R", "G", "B"}},
      {4, {"R", "G", "B", "A"}},
      {5, {"C0", "C1", "C2", "C3", "C4"}}};
  for (const auto& [channels, names] : defaults) {
    const fs::path path = dir / ("c" + std::to_string(channels) + ".exr");
    io::write_exr(path, Image(3, 2, channels, 0.5f), {});
    EXPECT_EQ(read_image(path).spec.channelnames, names) << channels << " channels";
  }
  io::ExrWriteOptions options;
  options.channel_names = {"albedo.R", "albedo.G", "albedo.B"};
  io::write_exr(dir / "custom.exr", Image(3, 2, 3, 0.25f), options);
  const ReadBack r = read_image(dir / "custom.exr");
  // OpenEXR stores channels sorted by name; these happen to sort as given.
  EXPECT_EQ(r.spec.channelnames, options.channel_names);
  EXPECT_EQ(r.pixels, std::vector<float>(18, 0.25f));

  options.channel_names = {"R", "G"};
  EXPECT_EQ(error_kind_of([&] { io::write_exr(dir / "bad.exr", Image(3, 2, 3), options); }),
            ErrorKind::Usage);
}

TEST(IoExr, DataAndDisplayWindows) {
  TempDir dir;
  const Image img = testing::random_image(7, 13, 3, 11);
  io::ExrWriteOptions options;
  options.pixel_type = io::PixelType::Float;
  options.data_window = {5, 9, 7, 13};
  options.display_width = 64;
  options.display_height = 48;
  io::write_exr(dir / "w.exr", img, options);
  const ReadBack r = read_image(dir / "w.exr");
  EXPECT_EQ(r.spec.x, 5);
  EXPECT_EQ(r.spec.y, 9);
  EXPECT_EQ(r.spec.width, 7);
  EXPECT_EQ(r.spec.height, 13);
  EXPECT_EQ(r.spec.full_x, 0);
  EXPECT_EQ(r.spec.full_y, 0);
  EXPECT_EQ(r.spec.full_width, 64);
  EXPECT_EQ(r.spec.full_height, 48);
  EXPECT_EQ(r.pixels, std::vector<float>(img.data(), img.data() + img.size()));

  // Without a display size, the display window is the image.
  io::write_exr(dir / "d.exr", img, {});
  const ReadBack d = read_image(dir / "d.exr");
  EXPECT_EQ(d.spec.full_width, 7);
  EXPECT_EQ(d.spec.full_height, 13);

  options.data_window = {0, 0, 8, 13};  // size does not match the image
  EXPECT_EQ(error_kind_of([&] { io::write_exr(dir / "bad.exr", img, options); }), ErrorKind::Usage);
}

TEST(IoExr, MetadataKeptLayoutDroppedResidueAttributesAdded) {
  TempDir dir;
  io::ExrWriteOptions options;
  options.compression = "piz";
  options.metadata.push_back(OIIO::ParamValue("Artist", "someone"));
  options.metadata.push_back(OIIO::ParamValue("studio:shot", "sq010_sh020"));
  options.metadata.push_back(OIIO::ParamValue("renderer:spp", 64));
  options.metadata.push_back(OIIO::ParamValue("compression", "none"));  // the source's layout: not ours
  options.metadata.push_back(OIIO::ParamValue("openexr:chunkCount", 99));
  options.metadata.push_back(OIIO::ParamValue("oiio:ColorSpace", "sRGB"));
  options.metadata.push_back(OIIO::ParamValue("residue:model", "old-model"));
  options.metadata.push_back(OIIO::ParamValue("residue:stale", "from an earlier run"));
  options.residue_attributes.push_back(OIIO::ParamValue("residue:model", "drn-v1"));
  options.residue_attributes.push_back(OIIO::ParamValue("residue:backend", "cpu"));
  options.residue_attributes.push_back(OIIO::ParamValue("residue:strength", 0.75f));
  options.residue_attributes.push_back(OIIO::ParamValue("residue:tile", OIIO::TypeDesc::INT64, 1, nullptr));
  io::write_exr(dir / "m.exr", Image(4, 4, 3, 1.0f), options);

  const ReadBack r = read_image(dir / "m.exr");
  const OIIO::ImageSpec& s = r.spec;
  EXPECT_EQ(s.get_string_attribute("compression"), "piz");
  EXPECT_EQ(s.get_string_attribute("Artist"), "someone");
  EXPECT_EQ(s.get_string_attribute("studio:shot"), "sq010_sh020");
  EXPECT_EQ(s.get_int_attribute("renderer:spp"), 64);
  EXPECT_NE(s.get_int_attribute("openexr:chunkCount"), 99);
  EXPECT_EQ(s.find_attribute("residue:stale"), nullptr);

  const OIIO::ParamValue* model = s.find_attribute("residue:model");
  ASSERT_NE(model, nullptr);
  EXPECT_EQ(model->type(), OIIO::TypeString);
  EXPECT_EQ(model->get_string(), "drn-v1");
  EXPECT_EQ(s.get_string_attribute("residue:backend"), "cpu");
  const OIIO::ParamValue* strength = s.find_attribute("residue:strength");
  ASSERT_NE(strength, nullptr);
  EXPECT_EQ(strength->type(), OIIO::TypeFloat);
  EXPECT_EQ(strength->get_float(), 0.75f);
  // A type EXR has no attribute for is written as text rather than dropped.
  const OIIO::ParamValue* tile = s.find_attribute("residue:tile");
  ASSERT_NE(tile, nullptr);
  EXPECT_EQ(tile->type(), OIIO::TypeString);
  EXPECT_EQ(tile->get_string(), "0");
}

TEST(IoExr, MetadataOfARealSourceDoesNotCarryItsLayout) {
  TempDir dir;
  // A tiled, piz-compressed source with a data window offset and a larger display window.
  OIIO::ImageSpec src(8, 6, 3, OIIO::TypeHalf);
  src.x = 3;
  src.y = 4;
  src.full_width = 40;
  src.full_height = 30;
  src.tile_width = 16;
  src.tile_height = 16;
  src.attribute("compression", "piz");
  src.attribute("openexr:lineOrder", "decreasingY");
  src.attribute("Copyright", "studio");
  const std::vector<float> pixels(8 * 6 * 3, 0.5f);
  {
    auto out = OIIO::ImageOutput::create("openexr");
    ASSERT_TRUE(out && out->open((dir / "src.exr").string(), src));
    ASSERT_TRUE(out->write_image(OIIO::TypeFloat, pixels.data()) && out->close()) << out->geterror();
  }
  const ReadBack source = read_image(dir / "src.exr");
  ASSERT_EQ(source.spec.tile_width, 16);

  io::ExrWriteOptions options;
  options.compression = "zip";
  options.metadata = source.spec.extra_attribs;
  io::write_exr(dir / "out.exr", Image(8, 6, 3, 0.5f), options);
  const ReadBack r = read_image(dir / "out.exr");
  EXPECT_EQ(r.spec.get_string_attribute("compression"), "zip");
  EXPECT_EQ(r.spec.tile_width, 0);  // scanlines
  EXPECT_EQ(r.spec.x, 0);
  EXPECT_EQ(r.spec.y, 0);
  EXPECT_EQ(r.spec.full_width, 8);
  EXPECT_EQ(r.spec.full_height, 6);
  EXPECT_NE(r.spec.get_string_attribute("openexr:lineOrder"), "decreasingY");
  EXPECT_EQ(r.spec.get_string_attribute("Copyright"), "studio");
  EXPECT_EQ(r.pixels, pixels);
}

// --- atomic writing
// ------------------------------------------------------------------------------------------

TEST(IoAtomic, ExistingFileIsNotReplacedWithoutOverwrite) {
  TempDir dir;
  const fs::path dest = dir / "out.exr";
  write_bytes(dest, "original bytes");
  bool called = false;
  std::string message;
  EXPECT_EQ(error_kind_of([&] { io::write_atomically(dest, false, [&](const fs::path&) { called = true; }); },
                          &message),
            ErrorKind::Output);
  EXPECT_FALSE(called) << "must fail before doing the work";
  EXPECT_NE(message.find(dest.string()), std::string::npos) << message;
  EXPECT_NE(message.find("--force"), std::string::npos) << message;
  EXPECT_EQ(read_bytes(dest), "original bytes");

  // The same through the EXR writer.
  EXPECT_EQ(error_kind_of([&] { io::write_exr(dest, Image(2, 2, 3), {}); }), ErrorKind::Output);
  EXPECT_EQ(read_bytes(dest), "original bytes");
  EXPECT_EQ(folder_entries(dir.path()), std::vector<std::string>{"out.exr"});
}

TEST(IoAtomic, FileCreatedMeanwhileIsNotClobbered) {
  TempDir dir;
  const fs::path dest = dir / "race.csv";
  std::string message;
  EXPECT_EQ(error_kind_of(
                [&] {
                  io::write_atomically(dest, false, [&](const fs::path& temp) {
                    write_bytes(temp, "ours");
                    write_bytes(dest, "someone else's");  // appears while we write
                  });
                },
                &message),
            ErrorKind::Output);
  EXPECT_NE(message.find(dest.string()), std::string::npos) << message;
  EXPECT_EQ(read_bytes(dest), "someone else's");
  EXPECT_EQ(folder_entries(dir.path()), std::vector<std::string>{"race.csv"});
}

TEST(IoAtomic, OverwriteReplaces) {
  TempDir dir;
  const fs::path dest = dir / "out.txt";
  write_bytes(dest, "old");
  io::write_atomically(dest, true, [](const fs::path& temp) { write_bytes(temp, "new"); });
  EXPECT_EQ(read_bytes(dest), "new");
  EXPECT_EQ(folder_entries(dir.path()), std::vector<std::string>{"out.txt"});

  io::write_exr(dest.parent_path() / "img.exr", Image(2, 2, 3, 1.0f), {});
  io::ExrWriteOptions options;
  options.overwrite = true;
  io::write_exr(dest.parent_path() / "img.exr", Image(5, 3, 3, 2.0f), options);
  EXPECT_EQ(read_image(dir / "img.exr").spec.width, 5);
}

TEST(IoAtomic, ThrowingCallbackLeavesNothing) {
  TempDir dir;
  const fs::path dest = dir / "out.exr";
  EXPECT_THROW(io::write_atomically(dest, false,
                                    [](const fs::path& temp) {
                                      write_bytes(temp, "half written");
                                      throw std::runtime_error("boom");
                                    }),
               std::runtime_error);
  EXPECT_TRUE(folder_entries(dir.path()).empty());

  // An existing file stays as it was when the callback fails under overwrite.
  write_bytes(dest, "keep me");
  EXPECT_THROW(io::write_atomically(dest, true, [](const fs::path&) { throw std::runtime_error("boom"); }),
               std::runtime_error);
  EXPECT_EQ(read_bytes(dest), "keep me");
  EXPECT_EQ(folder_entries(dir.path()), std::vector<std::string>{"out.exr"});
}

TEST(IoAtomic, MissingFolderIsAClearError) {
  TempDir dir;
  const fs::path folder = dir / "no" / "such";
  std::string message;
  EXPECT_EQ(error_kind_of([&] { io::write_exr(folder / "x.exr", Image(1, 1, 3), {}); }, &message),
            ErrorKind::Output);
  EXPECT_NE(message.find(folder.string()), std::string::npos) << message;
  EXPECT_NE(message.find("does not exist"), std::string::npos) << message;
}

TEST(IoAtomic, TempFileBesideDestinationWithItsExtension) {
  TempDir dir;
  const fs::path dest = dir / "beauty.denoised.exr";
  fs::path seen;
  io::write_atomically(dest, false, [&](const fs::path& temp) {
    seen = temp;
    EXPECT_TRUE(fs::exists(temp));
    write_bytes(temp, "x");
  });
  EXPECT_EQ(seen.parent_path(), dest.parent_path());
  EXPECT_EQ(seen.extension(), ".exr");
  EXPECT_EQ(seen.filename().string().rfind(".beauty.denoised.exr.residue-tmp-", 0), 0u) << seen;
  EXPECT_FALSE(fs::exists(seen));
  EXPECT_EQ(folder_entries(dir.path()), std::vector<std::string>{"beauty.denoised.exr"});

  // The result has the usual permissions (0666 less the umask), not a temp file's 0600.
  const mode_t mask = ::umask(0);
  ::umask(mask);
  struct stat st {};
  ASSERT_EQ(::stat(dest.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0666 & ~mask);
}

TEST(IoAtomic, RelativePathInCurrentFolder) {
  TempDir dir;
  const fs::path old = fs::current_path();
  fs::current_path(dir.path());
  EXPECT_NO_THROW(io::write_atomically("plain.txt", false, [](const fs::path& t) { write_bytes(t, "ok"); }));
  fs::current_path(old);
  EXPECT_EQ(read_bytes(dir / "plain.txt"), "ok");
}

// --- colormaps
// -----------------------------------------------------------------------------------------------

#include "core/image/colormap_tables.inc"

using Rgb = std::array<uint8_t, 3>;

TEST(Colormap, EndpointsAreMatplotlibs) {
  EXPECT_EQ(colormap_lookup(Colormap::Viridis, 0.0), (Rgb{68, 1, 84}));
  EXPECT_EQ(colormap_lookup(Colormap::Viridis, 1.0), (Rgb{253, 231, 37}));
  EXPECT_EQ(colormap_lookup(Colormap::Inferno, 0.0), (Rgb{0, 0, 4}));
  EXPECT_EQ(colormap_lookup(Colormap::Inferno, 1.0), (Rgb{252, 255, 164}));
  EXPECT_EQ(colormap_lookup(Colormap::Magma, 0.0), (Rgb{0, 0, 4}));
  EXPECT_EQ(colormap_lookup(Colormap::Magma, 1.0), (Rgb{252, 253, 191}));
  EXPECT_EQ(colormap_lookup(Colormap::Turbo, 0.0), (Rgb{48, 18, 59}));
  EXPECT_EQ(colormap_lookup(Colormap::Turbo, 1.0), (Rgb{122, 4, 3}));
  // matplotlib's RdBu_r: ColorBrewer's #053061 below, #67001f above, near white in the middle.
  EXPECT_EQ(colormap_lookup(Colormap::BlueRed, 0.0), (Rgb{5, 48, 97}));
  EXPECT_EQ(colormap_lookup(Colormap::BlueRed, 1.0), (Rgb{103, 0, 31}));
  for (uint8_t v : colormap_lookup(Colormap::BlueRed, 0.5)) EXPECT_GE(v, 245);
  // Clamped outside [0, 1].
  EXPECT_EQ(colormap_lookup(Colormap::Viridis, -3.0), colormap_lookup(Colormap::Viridis, 0.0));
  EXPECT_EQ(colormap_lookup(Colormap::Viridis, 7.0), colormap_lookup(Colormap::Viridis, 1.0));
}

TEST(Colormap, TablesAreMatplotlibs) {
  // Spot checks of the generated tables against matplotlib's _cm_listed.py (enum order).
  EXPECT_EQ(kColormapEntries, 256);
  EXPECT_EQ(kColormapTables[0][0][0], 0.267004f);  // viridis
  EXPECT_EQ(kColormapTables[0][128][1], 0.566949f);
  EXPECT_EQ(kColormapTables[0][255][2], 0.143936f);
  EXPECT_EQ(kColormapTables[1][255][1], 0.998364f);  // inferno
  EXPECT_EQ(kColormapTables[2][100][0], 0.537755f);  // magma
  EXPECT_EQ(kColormapTables[3][0][0], 0.18995f);     // turbo
}

TEST(Colormap, InterpolatesBetweenEntries) {
  for (int map = 0; map < 4; ++map)
    for (int i : {0, 17, 128, 254}) {
      const double t = (i + 0.25) / 255.0;
      const Rgb got = colormap_lookup(static_cast<Colormap>(map), t);
      for (int c = 0; c < 3; ++c) {
        const double want = 0.75 * kColormapTables[map][i][c] + 0.25 * kColormapTables[map][i + 1][c];
        EXPECT_EQ(got[c], std::lround(want * 255.0)) << "map " << map << " entry " << i << " channel " << c;
      }
      const Rgb exact = colormap_lookup(static_cast<Colormap>(map), i / 255.0);
      for (int c = 0; c < 3; ++c) EXPECT_EQ(exact[c], std::lround(kColormapTables[map][i][c] * 255.0));
    }
}

TEST(Colormap, Names) {
  for (Colormap m : {Colormap::Viridis, Colormap::Inferno, Colormap::Magma, Colormap::Turbo, Colormap::BlueRed})
    EXPECT_EQ(colormap_from_string(to_string(m)), m);
  EXPECT_EQ(colormap_from_string("Turbo"), Colormap::Turbo);
  EXPECT_EQ(colormap_from_string("jet"), std::nullopt);
  EXPECT_STREQ(to_string(Colormap::Magma), "magma");
}

Image one_row(const std::vector<float>& values) {
  Image img(static_cast<int64_t>(values.size()), 1, 1);
  std::copy(values.begin(), values.end(), img.data());
  return img;
}

Rgb pixel(const Image& rgb, int64_t x, int64_t y = 0) {
  Rgb out{};
  for (int c = 0; c < 3; ++c) out[c] = static_cast<uint8_t>(std::lround(rgb.at(x, y, c) * 255.0f));
  return out;
}

TEST(Colormap, AutomaticRangeIgnoresNonFinite) {
  const Image map = one_row({kNaN, kInf, 2.0f, 4.0f, -kInf, 3.0f});
  EXPECT_EQ(resolve_range(map, {}), (std::pair<double, double>{2.0, 4.0}));
  ColorScale log;
  log.log = true;
  EXPECT_EQ(resolve_range(one_row({-1.0f, 0.0f, 0.5f, 8.0f, kInf}), log),
            (std::pair<double, double>{0.5, 8.0}));
  // No positive value: lo = hi * 1e-6.
  log.hi = 10.0;
  const auto [lo, hi] = resolve_range(one_row({-1.0f, 0.0f}), log);
  EXPECT_EQ(hi, 10.0);
  EXPECT_DOUBLE_EQ(lo, 1e-5);
  // Nothing finite at all.
  EXPECT_EQ(resolve_range(one_row({kNaN, kInf}), {}), (std::pair<double, double>{0.0, 1.0}));
}

// A signed map's automatic range is symmetric about 0, so that 0 is the diverging map's middle; an explicit bound
// gives the other its negative; a symmetric log scale is refused.
TEST(Colormap, SymmetricRangeCentresZero) {
  ColorScale s;
  s.symmetric = true;
  EXPECT_EQ(resolve_range(one_row({-0.2f, 0.05f, kNaN, kInf}), s), (std::pair<double, double>{-0.2f, 0.2f}));
  EXPECT_EQ(resolve_range(one_row({0.0f, 0.5f}), s), (std::pair<double, double>{-0.5, 0.5}));
  s.hi = 0.1;
  EXPECT_EQ(resolve_range(one_row({-0.2f, 0.05f}), s), (std::pair<double, double>{-0.1, 0.1}));
  const Image rgb = apply_colormap(one_row({-0.1f, 0.0f, 0.1f}), Colormap::BlueRed, s);
  EXPECT_EQ(pixel(rgb, 1), colormap_lookup(Colormap::BlueRed, 0.5));
  EXPECT_EQ(pixel(rgb, 0), colormap_lookup(Colormap::BlueRed, 0.0));
  s.log = true;
  EXPECT_EQ(error_kind_of([&] { resolve_range(one_row({1.0f}), s); }), ErrorKind::Usage);
}

TEST(Colormap, NanIsInvalidAndInfClamps) {
  const Image rgb = apply_colormap(one_row({kNaN, 0.0f, 1.0f, kInf, -kInf}), Colormap::Viridis, {});
  ASSERT_EQ(rgb.channels(), 3);
  EXPECT_EQ(pixel(rgb, 0), kInvalidColor);
  EXPECT_EQ(pixel(rgb, 1), colormap_lookup(Colormap::Viridis, 0.0));
  EXPECT_EQ(pixel(rgb, 2), colormap_lookup(Colormap::Viridis, 1.0));
  EXPECT_EQ(pixel(rgb, 3), colormap_lookup(Colormap::Viridis, 1.0));
  EXPECT_EQ(pixel(rgb, 4), colormap_lookup(Colormap::Viridis, 0.0));
  for (size_t i = 0; i < rgb.size(); ++i) {
    EXPECT_GE(rgb.data()[i], 0.0f);
    EXPECT_LE(rgb.data()[i], 1.0f);
  }
}

TEST(Colormap, LinearAndLogScales) {
  ColorScale linear;
  linear.lo = 1.0;
  linear.hi = 5.0;
  const Image lin = apply_colormap(one_row({0.0f, 2.0f, 5.0f, 9.0f}), Colormap::Magma, linear);
  EXPECT_EQ(pixel(lin, 0), colormap_lookup(Colormap::Magma, 0.0));
  EXPECT_EQ(pixel(lin, 1), colormap_lookup(Colormap::Magma, 0.25));
  EXPECT_EQ(pixel(lin, 2), colormap_lookup(Colormap::Magma, 1.0));
  EXPECT_EQ(pixel(lin, 3), colormap_lookup(Colormap::Magma, 1.0));

  ColorScale log;
  log.log = true;  // automatic: lo = 0.001 (smallest positive), hi = 1
  const Image lg = apply_colormap(one_row({0.001f, 0.01f, 0.1f, 1.0f, 0.0f, -2.0f, 0.0316227766f}),
                                  Colormap::Inferno, log);
  EXPECT_EQ(pixel(lg, 0), colormap_lookup(Colormap::Inferno, 0.0));
  EXPECT_EQ(pixel(lg, 1), colormap_lookup(Colormap::Inferno, 1.0 / 3.0));
  EXPECT_EQ(pixel(lg, 2), colormap_lookup(Colormap::Inferno, 2.0 / 3.0));
  EXPECT_EQ(pixel(lg, 3), colormap_lookup(Colormap::Inferno, 1.0));
  EXPECT_EQ(pixel(lg, 4), colormap_lookup(Colormap::Inferno, 0.0));  // non-positive: bottom
  EXPECT_EQ(pixel(lg, 5), colormap_lookup(Colormap::Inferno, 0.0));
  EXPECT_EQ(pixel(lg, 6), colormap_lookup(Colormap::Inferno, 0.5));  // 10^-1.5
}

TEST(Colormap, EqualBoundsAreSafe) {
  const Image flat = apply_colormap(one_row({3.0f, 3.0f}), Colormap::Turbo, {});
  EXPECT_EQ(pixel(flat, 0), colormap_lookup(Colormap::Turbo, 0.5));
  ColorScale fixed;
  fixed.lo = 1.0;
  fixed.hi = 1.0;
  const Image step = apply_colormap(one_row({0.0f, 1.0f, 2.0f, kNaN}), Colormap::Turbo, fixed);
  EXPECT_EQ(pixel(step, 0), colormap_lookup(Colormap::Turbo, 0.0));
  EXPECT_EQ(pixel(step, 1), colormap_lookup(Colormap::Turbo, 0.5));
  EXPECT_EQ(pixel(step, 2), colormap_lookup(Colormap::Turbo, 1.0));
  EXPECT_EQ(pixel(step, 3), kInvalidColor);
  ColorScale log = fixed;
  log.log = true;
  const Image lstep = apply_colormap(one_row({0.5f, 1.0f, 2.0f}), Colormap::Turbo, log);
  EXPECT_EQ(pixel(lstep, 1), colormap_lookup(Colormap::Turbo, 0.5));
}

TEST(Colormap, BadScalesAreUsageErrors) {
  ColorScale inverted;
  inverted.lo = 2.0;
  inverted.hi = 1.0;
  EXPECT_EQ(error_kind_of([&] { resolve_range(one_row({1.0f}), inverted); }), ErrorKind::Usage);
  ColorScale log;
  log.log = true;
  log.lo = 0.0;
  EXPECT_EQ(error_kind_of([&] { resolve_range(one_row({1.0f}), log); }), ErrorKind::Usage);
  EXPECT_EQ(error_kind_of([&] { apply_colormap(Image(2, 2, 3), Colormap::Viridis, {}); }), ErrorKind::Usage);
}

TEST(Colormap, PngReadsBackAsTheLookup) {
  TempDir dir;
  Image map(9, 4, 1);
  for (int64_t y = 0; y < 4; ++y)
    for (int64_t x = 0; x < 9; ++x) map.at(x, y) = static_cast<float>(x + 9 * y);  // 0 .. 35
  map.at(3, 2) = kNaN;
  io::MapPngOptions options;
  options.colormap = Colormap::Inferno;
  const fs::path path = dir / "map.png";
  io::write_map_png(path, map, options);
  auto in = OIIO::ImageInput::open(path.string());
  ASSERT_TRUE(in) << OIIO::geterror();
  const OIIO::ImageSpec spec = in->spec();
  EXPECT_EQ(spec.width, 9);
  EXPECT_EQ(spec.height, 4);
  ASSERT_EQ(spec.nchannels, 3);
  EXPECT_EQ(spec.format, OIIO::TypeUInt8);
  std::vector<uint8_t> bytes(9 * 4 * 3);
  ASSERT_TRUE(in->read_image(0, 0, 0, -1, OIIO::TypeUInt8, bytes.data()));
  for (int64_t y = 0; y < 4; ++y)
    for (int64_t x = 0; x < 9; ++x) {
      const size_t i = static_cast<size_t>((y * 9 + x) * 3);
      const Rgb got{bytes[i], bytes[i + 1], bytes[i + 2]};
      const Rgb want = (x == 3 && y == 2)
                           ? kInvalidColor
                           : colormap_lookup(Colormap::Inferno, static_cast<double>(x + 9 * y) / 35.0);
      EXPECT_EQ(got, want) << x << "," << y;
    }
  EXPECT_EQ(error_kind_of([&] { io::write_map_png(path, map, options); }), ErrorKind::Output);
  EXPECT_EQ(folder_entries(dir.path()), std::vector<std::string>{"map.png"});
}

TEST(Colormap, MapExrKeepsValues) {
  TempDir dir;
  Image map = testing::random_image(6, 5, 1, 5, -1.0f, 1.0f);
  map.at(1, 1) = kNaN;
  map.at(2, 1) = kInf;
  io::write_map_exr(dir / "map.exr", map, false);
  const ReadBack r = read_image(dir / "map.exr");
  EXPECT_EQ(r.spec.channelnames, std::vector<std::string>{"Y"});
  EXPECT_EQ(r.spec.format, OIIO::TypeFloat);
  ASSERT_EQ(r.pixels.size(), map.size());
  for (size_t i = 0; i < map.size(); ++i) EXPECT_EQ(bits(r.pixels[i]), bits(map.data()[i]));
  EXPECT_EQ(error_kind_of([&] { io::write_map_exr(dir / "map.exr", map, false); }), ErrorKind::Output);
  EXPECT_NO_THROW(io::write_map_exr(dir / "map.exr", map, true));
}

// --- metrics reports
// -----------------------------------------------------------------------------------------

io::MetricsReport sample_report() {
  io::MetricsReport report;
  report.reference_file = "/renders/ref 4096spp.exr";
  report.width = 1920;
  report.height = 1080;
  report.options.eps = 0.01;
  report.options.ssim_space = metrics::SsimSpace::Linear;
  report.options.roi = Rect{10, 20, 300, 400};
  metrics::Scores noisy;
  noisy.mse = 0.1 + 0.2;
  noisy.relmse = 1.0 / 3.0;
  noisy.psnr = 23.456789012345678;
  noisy.ssim = 0.87654321098765432;
  noisy.pixels = 1920 * 1080 - 7;
  noisy.excluded_test = 5;
  noisy.excluded_reference = 2;
  metrics::Scores same;
  same.mse = 0.0;
  same.relmse = 1e-300;
  same.psnr = std::numeric_limits<double>::infinity();
  same.ssim = 1.0;
  same.pixels = 1920 * 1080;
  report.rows = {{"noisy, 16spp", "/renders/noisy \"a\".exr", noisy, 0.1234567890123},
                 {"denoised", "denoised.exr", same, std::nullopt, 0.0123456789012345}};
  report.flip = metrics::FlipExposures{-2.5, 5.0, 8};
  return report;
}

double json_double(const nlohmann::json& j) {
  if (j.is_string()) {
    const std::string s = j.get<std::string>();
    if (s == "inf") return std::numeric_limits<double>::infinity();
    if (s == "-inf") return -std::numeric_limits<double>::infinity();
    if (s == "nan") return std::numeric_limits<double>::quiet_NaN();
    ADD_FAILURE() << "unexpected string " << s;
  }
  return j.get<double>();
}

// Every field, doubles compared with == (exact; the sample has no NaN).
auto score_fields(const metrics::Scores& s) {
  return std::tuple(s.mse, s.relmse, s.psnr, s.ssim, s.pixels, s.excluded_test, s.excluded_reference);
}

TEST(IoMetrics, JsonRoundTrip) {
  const io::MetricsReport report = sample_report();
  TempDir dir;
  io::write_metrics(dir / "m.json", report, false);
  const std::string text = read_bytes(dir / "m.json");
  EXPECT_EQ(text, io::to_json(report));
  const nlohmann::json j = nlohmann::json::parse(text);  // strict JSON: no bare inf/nan
  EXPECT_EQ(j["reference_file"], report.reference_file);
  EXPECT_EQ(j["width"], 1920);
  EXPECT_EQ(j["height"], 1080);
  EXPECT_EQ(j["options"]["eps"].get<double>(), 0.01);
  EXPECT_EQ(j["options"]["ssim_space"], "linear");
  EXPECT_EQ(j["options"]["roi"], (nlohmann::json{{"x", 10}, {"y", 20}, {"width", 300}, {"height", 400}}));
  EXPECT_EQ(j["formula"], metrics::formula_text(report.options));
  ASSERT_EQ(j["rows"].size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    const nlohmann::json& row = j["rows"][i];
    EXPECT_EQ(row["name"], report.rows[i].name);
    EXPECT_EQ(row["test_file"], report.rows[i].test_file);
    metrics::Scores s;
    s.mse = json_double(row["mse"]);
    s.relmse = json_double(row["relmse"]);
    s.psnr = json_double(row["psnr"]);
    s.ssim = json_double(row["ssim"]);
    s.pixels = row["pixels"].get<int64_t>();
    s.excluded_test = row["excluded_test"].get<int64_t>();
    s.excluded_reference = row["excluded_reference"].get<int64_t>();
    EXPECT_EQ(score_fields(s), score_fields(report.rows[i].scores));
  }
  EXPECT_EQ(j["rows"][1]["psnr"], "inf");
  EXPECT_EQ(j["rows"][0]["hdr_flip"].get<double>(), 0.1234567890123);
  EXPECT_TRUE(j["rows"][1]["hdr_flip"].is_null()) << "not computed: null, not a number";
  EXPECT_TRUE(j["rows"][0]["temporal_relmse_compensated"].is_null()) << "not computed: null, not a number";
  EXPECT_EQ(j["rows"][1]["temporal_relmse_compensated"].get<double>(), 0.0123456789012345);
  EXPECT_EQ(j["flip"]["exposures"]["count"], 8);
  EXPECT_EQ(j["flip"]["exposures"]["start"].get<double>(), -2.5);
  EXPECT_EQ(j["flip"]["definition"], metrics::flip_formula_text(*report.flip));

  io::MetricsReport whole = report;
  whole.options.roi.reset();
  whole.options.ssim_space = metrics::SsimSpace::Tonemapped;
  const nlohmann::json w = nlohmann::json::parse(io::to_json(whole));
  EXPECT_TRUE(w["options"]["roi"].is_null());
  EXPECT_EQ(w["options"]["ssim_space"], "tonemapped");
}

// Splits one CSV line (RFC 4180 quoting, no line breaks inside fields).
std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"')
        fields.back() += line[++i];
      else if (c == '"')
        quoted = false;
      else
        fields.back() += c;
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  return fields;
}

TEST(IoMetrics, CsvRoundTrip) {
  const io::MetricsReport report = sample_report();
  TempDir dir;
  io::write_metrics(dir / "m.CSV", report, false);
  std::istringstream text(read_bytes(dir / "m.CSV"));
  std::vector<std::string> lines;
  for (std::string line; std::getline(text, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0], "name,test_file,mse,relmse,psnr,ssim,pixels,excluded_test,excluded_reference,hdr_flip,"
                      "temporal_relmse_compensated");
  for (size_t i = 0; i < 2; ++i) {
    const auto f = split_csv(lines[i + 1]);
    ASSERT_EQ(f.size(), 11u) << lines[i + 1];
    EXPECT_EQ(f[9], i == 0 ? "0.1234567890123" : "") << "HDR-FLIP, empty where not computed";
    EXPECT_EQ(f[10], i == 1 ? "0.0123456789012345" : "") << "the temporal error, empty where not computed";
    EXPECT_EQ(f[0], report.rows[i].name);
    EXPECT_EQ(f[1], report.rows[i].test_file);
    metrics::Scores s;
    s.mse = std::strtod(f[2].c_str(), nullptr);
    s.relmse = std::strtod(f[3].c_str(), nullptr);
    s.psnr = std::strtod(f[4].c_str(), nullptr);
    s.ssim = std::strtod(f[5].c_str(), nullptr);
    s.pixels = std::stoll(f[6]);
    s.excluded_test = std::stoll(f[7]);
    s.excluded_reference = std::stoll(f[8]);
    EXPECT_EQ(score_fields(s), score_fields(report.rows[i].scores));
  }
  EXPECT_EQ(split_csv(lines[2])[4], "inf");
  EXPECT_EQ(lines[1].rfind("\"noisy, 16spp\",\"/renders/noisy \"\"a\"\".exr\",", 0), 0u) << lines[1];
}

TEST(IoMetrics, FormatByExtensionAndOverwriteProtection) {
  const io::MetricsReport report = sample_report();
  TempDir dir;
  EXPECT_EQ(error_kind_of([&] { io::write_metrics(dir / "m.txt", report, false); }), ErrorKind::Usage);
  EXPECT_EQ(error_kind_of([&] { io::write_metrics(dir / "json", report, false); }), ErrorKind::Usage);
  EXPECT_TRUE(folder_entries(dir.path()).empty());

  write_bytes(dir / "m.json", "precious");
  std::string message;
  EXPECT_EQ(error_kind_of([&] { io::write_metrics(dir / "m.json", report, false); }, &message),
            ErrorKind::Output);
  EXPECT_NE(message.find((dir / "m.json").string()), std::string::npos);
  EXPECT_EQ(read_bytes(dir / "m.json"), "precious");
  io::write_metrics(dir / "m.json", report, true);
  EXPECT_EQ(read_bytes(dir / "m.json"), io::to_json(report));
  EXPECT_EQ(folder_entries(dir.path()), std::vector<std::string>{"m.json"});
}

}  // namespace
}  // namespace residue
