// AOV stack loading: real Cycles and Tungsten renders, and files written here for every naming convention.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>

#include <gtest/gtest.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imageio.h>

#include "core/aov/aov_loader.h"
#include "core/aov/channel_naming.h"
#include "core/aov/conventions.h"
#include "core/aov/other_layers.h"
#include "core/util/error.h"
#include "support/exr_fixture.h"
#include "support/test_support.h"

namespace residue {
namespace {

using testing::as_half;
using testing::constant_channel;
using testing::FixtureChannel;
using testing::FixturePart;
using testing::TempDir;
using testing::write_fixture_exr;

// A channel whose value encodes its position and a tag, so a misplaced pixel or channel is caught.
FixtureChannel coded(const std::string& name, float tag, bool half = false) {
  return {name, half, [tag](int x, int y) { return tag + 0.001f * static_cast<float>(x) + 0.1f * static_cast<float>(y); }};
}
float code(float tag, int x, int y) { return tag + 0.001f * static_cast<float>(x) + 0.1f * static_cast<float>(y); }

FixturePart part(int w, int h, std::vector<FixtureChannel> channels) {
  FixturePart p;
  p.width = w;
  p.height = h;
  p.channels = std::move(channels);
  return p;
}

// Expects each AOV channel c of `role` to hold code(tag + c, x, y) everywhere.
void expect_coded(const AovStack& s, AovRole role, float tag) {
  const Aov* aov = s.find(role);
  ASSERT_NE(aov, nullptr) << to_string(role) << " missing";
  for (int c = 0; c < aov->image.channels(); ++c)
    for (int64_t y = 0; y < s.height(); ++y)
      for (int64_t x = 0; x < s.width(); ++x)
        ASSERT_FLOAT_EQ(aov->image.at(x, y, c), code(tag + static_cast<float>(c), static_cast<int>(x), static_cast<int>(y)))
            << to_string(role) << " channel " << c << " at " << x << "," << y;
}

std::string error_of(const std::function<void()>& f, ErrorKind* kind = nullptr) {
  try {
    f();
  } catch (const Error& e) {
    if (kind) *kind = e.kind();
    return e.what();
  }
  return "";
}

// --- real renders -------------------------------------------------------------------------------------------

TEST(AovCycles, StarterSceneLoadsEveryPass) {
  const auto dir = testing::shared_dataset("cycles-starter/s100");
  RESIDUE_REQUIRE_SHARED(dir);
  LoadOptions o;
  o.reference = dir / "reference.exr";
  const AovStack s = load_aov_stack({dir / "noisy_a.exr"}, o);
  EXPECT_EQ(s.convention, "Blender Cycles");
  EXPECT_EQ(s.width(), 256);
  EXPECT_EQ(s.height(), 256);
  ASSERT_TRUE(s.albedo && s.normal && s.depth && s.reference);
  EXPECT_FALSE(s.variance);
  EXPECT_EQ(s.color.source.channels,
            (std::vector<std::string>{"ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B"}));
  EXPECT_EQ(s.color.source.pixel_types, (std::vector<std::string>{"half", "half", "half"}));
  EXPECT_EQ(s.normal->source.channels.front(), "ViewLayer.Denoising Normal.X");
  EXPECT_EQ(s.normal->source.pixel_types.front(), "float");
  EXPECT_EQ(s.depth->source.channels.front(), "ViewLayer.Denoising Depth.Z");
  EXPECT_EQ(s.normal_space, NormalSpace::Camera);
  EXPECT_EQ(s.depth_kind, DepthKind::RayLength);
  EXPECT_TRUE(s.world_to_camera.has_value()) << "the starter set writes the camera into the Note attribute";

  // Values equal a direct OIIO read of the same channels.
  OIIO::ImageBuf raw((dir / "noisy_a.exr").string());
  ASSERT_TRUE(raw.read(0, 0, true, OIIO::TypeFloat));
  const int nx = raw.spec().channelindex("ViewLayer.Denoising Normal.X");
  const int nz = raw.spec().channelindex("ViewLayer.Denoising Normal.Z");
  const int cr = raw.spec().channelindex("ViewLayer.Combined.R");
  double mean_z = 0;
  for (int y = 0; y < 256; y += 17)
    for (int x = 0; x < 256; x += 13) {
      EXPECT_EQ(s.color.image.at(x, y, 0), raw.getchannel(x, y, 0, cr));
      EXPECT_EQ(s.normal->image.at(x, y, 0), raw.getchannel(x, y, 0, nx));
      // Cycles' denoising normal has +z along the view direction; the stack's +z points at the viewer.
      EXPECT_EQ(s.normal->image.at(x, y, 2), -raw.getchannel(x, y, 0, nz));
      mean_z += s.normal->image.at(x, y, 2);
    }
  EXPECT_GT(mean_z, 0.0) << "visible surfaces face the camera: +z towards the viewer on average";
}

TEST(AovCycles, EveryStarterSceneLoads) {
  const auto root = testing::shared_dataset("cycles-starter");
  RESIDUE_REQUIRE_SHARED(root);
  int scenes = 0;
  for (const auto& entry : std::filesystem::directory_iterator(root)) {
    if (!entry.is_directory()) continue;
    const AovStack s = load_aov_stack({entry.path() / "noisy_b.exr"});
    EXPECT_EQ(s.convention, "Blender Cycles") << entry.path();
    EXPECT_TRUE(s.albedo && s.normal && s.depth) << entry.path();
    EXPECT_EQ(s.color.non_finite.total(), 0) << entry.path();
    ++scenes;
  }
  EXPECT_GE(scenes, 60);
}

TEST(AovTungsten, FolderIsAFileSetWithWorldNormals) {
  const auto dir = testing::shared_dataset("tungsten-example/cornell-box");
  RESIDUE_REQUIRE_SHARED(dir);
  const AovStack s = load_aov_stack({dir});
  EXPECT_EQ(s.convention, "Tungsten file set");
  EXPECT_EQ(s.width(), 384);
  ASSERT_TRUE(s.albedo && s.normal && s.depth && s.variance && s.reference);
  EXPECT_EQ(s.normal_space, NormalSpace::World);
  EXPECT_EQ(std::filesystem::path(s.depth->source.file).filename(), "depth.exr");
  EXPECT_EQ(s.depth->source.channels, std::vector<std::string>{"Y"});
  EXPECT_EQ(std::filesystem::path(s.variance->source.file).filename(), "colorVariance.exr");
  EXPECT_EQ(std::filesystem::path(s.reference->source.file).filename(), "reference.exr");
  // Tungsten's albedo includes emission: values above 1 are kept.
  float max_albedo = 0;
  for (size_t i = 0; i < s.albedo->image.size(); ++i) max_albedo = std::max(max_albedo, s.albedo->image.data()[i]);
  EXPECT_GT(max_albedo, 1.0f);
  // Loading color.exr itself finds the same siblings.
  const AovStack t = load_aov_stack({dir / "color.exr"});
  EXPECT_EQ(t.convention, "Tungsten file set");
  EXPECT_TRUE(t.variance.has_value());
}

// --- every naming convention, on files written here ---------------------------------------------------------

TEST(AovConventions, CyclesPlanarDepthSentinelAndWorldNormals) {
  TempDir tmp;
  const auto f = tmp / "cycles.exr";
  write_fixture_exr(f, {part(7, 13, {coded("ViewLayer.Combined.R", 10, true), coded("ViewLayer.Combined.G", 11, true),
                                     coded("ViewLayer.Combined.B", 12, true), constant_channel("ViewLayer.Combined.A", 1, true),
                                     coded("ViewLayer.Normal.X", 20), coded("ViewLayer.Normal.Y", 21),
                                     coded("ViewLayer.Normal.Z", 22),
                                     {"ViewLayer.Depth.Z", false, [](int x, int) { return x < 3 ? 1e10f : 4.0f; }}})});
  const AovStack s = load_aov_stack({f});
  EXPECT_EQ(s.convention, "Blender Cycles");
  EXPECT_EQ(s.normal_space, NormalSpace::World);
  EXPECT_EQ(s.depth_kind, DepthKind::Planar);
  EXPECT_EQ(s.depth_background_pixels, 3 * 13);
  EXPECT_EQ(s.depth->image.at(0, 0), 0.0f) << "background sentinel 1e10 becomes 0";
  EXPECT_EQ(s.depth->image.at(5, 5), 4.0f);
  EXPECT_FALSE(s.albedo.has_value());
  expect_coded(s, AovRole::Normal, 20);
  // Half channels come back as the half value of what was written.
  EXPECT_EQ(s.color.image.at(3, 4, 1), as_half(code(11, 3, 4)));
}

TEST(AovConventions, CyclesDenoisingDepthBackgroundIsZeroAlready) {
  TempDir tmp;
  const auto f = tmp / "cycles.exr";
  write_fixture_exr(f, {part(4, 4, {coded("ViewLayer.Combined.R", 1), coded("ViewLayer.Combined.G", 2), coded("ViewLayer.Combined.B", 3),
                                    {"ViewLayer.Denoising Depth.Z", false, [](int x, int) { return x == 0 ? 0.0f : 2.5f; }},
                                    {"ViewLayer.Depth.Z", false, [](int, int) { return 1e10f; }}})});
  const AovStack s = load_aov_stack({f});
  EXPECT_EQ(s.depth->source.channels.front(), "ViewLayer.Denoising Depth.Z") << "the denoising pass is preferred";
  EXPECT_EQ(s.depth->image.at(1, 1), 2.5f);
  EXPECT_EQ(s.depth->image.at(0, 1), 0.0f);
}

TEST(AovConventions, CyclesSecondViewLayerByPrefix) {
  TempDir tmp;
  const auto f = tmp / "layers.exr";
  write_fixture_exr(f, {part(3, 2, {coded("Fg.Combined.R", 1), coded("Fg.Combined.G", 2), coded("Fg.Combined.B", 3),
                                    coded("Bg.Combined.R", 7), coded("Bg.Combined.G", 8), coded("Bg.Combined.B", 9)})});
  LoadOptions o;
  o.mapping.layer_prefix = "Bg";
  const AovStack s = load_aov_stack({f}, o);
  expect_coded(s, AovRole::Color, 7);
  const AovStack first = load_aov_stack({f});
  EXPECT_FALSE(first.notes.empty()) << "several view layers are worth a note";
}

TEST(AovConventions, Arnold) {
  TempDir tmp;
  const auto f = tmp / "arnold.exr";
  write_fixture_exr(f, {part(5, 3, {coded("R", 10), coded("G", 11), coded("B", 12), constant_channel("A", 1),
                                    coded("N.R", 20), coded("N.G", 21), coded("N.B", 22), coded("Z", 40),
                                    coded("denoise_albedo.R", 30), coded("denoise_albedo.G", 31),
                                    coded("denoise_albedo.B", 32)})});
  const AovStack s = load_aov_stack({f});
  EXPECT_EQ(s.convention, "Arnold");
  expect_coded(s, AovRole::Color, 10);
  expect_coded(s, AovRole::Normal, 20);
  expect_coded(s, AovRole::Albedo, 30);
  expect_coded(s, AovRole::Depth, 40);
  EXPECT_EQ(s.normal_space, NormalSpace::World);
}

// pbrt-v4's gbuffer film, with the channels in the order it writes them: shading normals (Ns, not N) in camera space
// with +z along the view direction, depth from P.Z (0 where no surface was hit), no variance (pbrt's is the
// samples' variance, not the estimate's).
std::vector<FixtureChannel> pbrt_gbuffer_channels() {
  std::vector<FixtureChannel> ch = {coded("R", 10), coded("G", 11), coded("B", 12),
                                    coded("Albedo.R", 30), coded("Albedo.G", 31), coded("Albedo.B", 32),
                                    coded("P.X", 60), coded("P.Y", 61),
                                    {"P.Z", false, [](int x, int y) { return x == 0 && y == 0 ? 0.0f : code(40, x, y); }},
                                    coded("dzdx", 70), coded("dzdy", 71),
                                    coded("N.X", 80), coded("N.Y", 81), coded("N.Z", 82),
                                    coded("Ns.X", 20), coded("Ns.Y", 21), coded("Ns.Z", 22),
                                    coded("u", 90), coded("v", 91)};
  for (const char* c : {"R", "G", "B"}) ch.push_back(coded(std::string("Variance.") + c, 50));
  for (const char* c : {"R", "G", "B"}) ch.push_back(coded(std::string("RelativeVariance.") + c, 55));
  return ch;
}

TEST(AovConventions, PbrtGbufferFilm) {
  TempDir tmp;
  const auto f = tmp / "pbrt.exr";
  write_fixture_exr(f, {part(5, 3, pbrt_gbuffer_channels())});
  const AovStack s = load_aov_stack({f});
  EXPECT_EQ(s.convention, "pbrt-v4 (gbuffer film)");
  expect_coded(s, AovRole::Color, 10);
  expect_coded(s, AovRole::Albedo, 30);
  EXPECT_EQ(s.normal_space, NormalSpace::Camera);
  ASSERT_TRUE(s.normal && s.depth);
  EXPECT_EQ(s.normal->source.layer, "Ns");
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 5; ++x) {
      EXPECT_FLOAT_EQ(s.normal->image.at(x, y, 0), code(20, x, y));
      EXPECT_FLOAT_EQ(s.normal->image.at(x, y, 1), code(21, x, y));
      EXPECT_FLOAT_EQ(s.normal->image.at(x, y, 2), -code(22, x, y));  // pbrt's camera looks down +z
      EXPECT_FLOAT_EQ(s.depth->image.at(x, y), x == 0 && y == 0 ? 0.0f : code(40, x, y));
    }
  EXPECT_EQ(s.depth->source.channels, std::vector<std::string>{"P.Z"});
  EXPECT_EQ(s.depth_kind, DepthKind::Planar);
  // Its Variance is the samples': without the samplesPerPixel header it cannot become the estimate's.
  EXPECT_FALSE(s.variance.has_value());
  EXPECT_TRUE(std::any_of(s.notes.begin(), s.notes.end(), [](const std::string& n) {
    return n.find("no variance") != std::string::npos && n.find("samplesPerPixel") != std::string::npos;
  }));

  // With the header pbrt-v4 writes, the estimate's variance: the samples' over their count.
  const auto with_spp = tmp / "pbrt_spp.exr";
  FixturePart p = part(5, 3, pbrt_gbuffer_channels());
  p.int_attributes = {{"samplesPerPixel", 16}};
  write_fixture_exr(with_spp, {p});
  const AovStack v = load_aov_stack({with_spp});
  ASSERT_TRUE(v.variance.has_value());
  EXPECT_EQ(v.variance->source.layer, "Variance");
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 5; ++x)
      for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(v.variance->image.at(x, y, c), code(50, x, y) / 16.0f);

  // Rendered with coordinatesystem "world": P is in world space too, so its z is no depth.
  LoadOptions world;
  world.normal_space = NormalSpace::World;
  const AovStack w = load_aov_stack({f}, world);
  EXPECT_EQ(w.normal_space, NormalSpace::World);
  EXPECT_FALSE(w.depth.has_value());
  EXPECT_TRUE(std::any_of(w.notes.begin(), w.notes.end(),
                          [](const std::string& n) { return n.find("no depth") != std::string::npos; }));
}

// "N" is Arnold's name for its normal, but also the name anyone gives one: R,G,B with albedo and N is a plain file
// (normals of unknown space, said), not Arnold's (whose normals are world space, turned by a camera in the header).
// Arnold is known by its denoise_albedo or diffuse_albedo, or by N with Z.
TEST(AovConventions, NWithAlbedoAloneIsPlainNotArnold) {
  TempDir tmp;
  const auto plain = tmp / "plain.exr";
  write_fixture_exr(plain, {part(5, 3, {coded("R", 10), coded("G", 11), coded("B", 12), coded("albedo.R", 30),
                                        coded("albedo.G", 31), coded("albedo.B", 32), coded("N.X", 20),
                                        coded("N.Y", 21), coded("N.Z", 22)})});
  const AovStack s = load_aov_stack({plain});
  EXPECT_EQ(s.convention, "plain R,G,B with named layers");
  expect_coded(s, AovRole::Normal, 20);
  expect_coded(s, AovRole::Albedo, 30);
  EXPECT_EQ(s.normal_space, NormalSpace::Unknown);
  EXPECT_TRUE(std::any_of(s.notes.begin(), s.notes.end(),
                          [](const std::string& n) { return n.find("--normal-space") != std::string::npos; }))
      << "the unknown normal space is said, with the option that states it";

  for (const char* mark : {"diffuse_albedo", "denoise_albedo"}) {
    const auto arnold = tmp / (std::string(mark) + ".exr");
    const std::string m = mark;
    write_fixture_exr(arnold, {part(5, 3, {coded("R", 10), coded("G", 11), coded("B", 12), coded(m + ".R", 30),
                                           coded(m + ".G", 31), coded(m + ".B", 32), coded("N.X", 20),
                                           coded("N.Y", 21), coded("N.Z", 22)})});
    const AovStack a = load_aov_stack({arnold});
    EXPECT_EQ(a.convention, "Arnold") << mark;
    EXPECT_EQ(a.normal_space, NormalSpace::World) << mark;
  }
  const auto nz = tmp / "nz.exr";
  write_fixture_exr(nz, {part(5, 3, {coded("R", 10), coded("G", 11), coded("B", 12), coded("N.X", 20),
                                     coded("N.Y", 21), coded("N.Z", 22), coded("Z", 40)})});
  EXPECT_EQ(load_aov_stack({nz}).convention, "Arnold");
}

// The layers no AOV took are listed for browsing, each read with its own values: the colour's alpha alone, a light
// pass, a group of four cut into three and its alpha, one of five into threes; the channels a role took are not.
TEST(OtherLayers, EveryUnrecognisedChannelIsALayerWithItsValues) {
  TempDir tmp;
  const auto f = tmp / "layers.exr";
  std::vector<FixtureChannel> ch;
  const auto group = [&](const std::string& layer, const std::vector<std::string>& names, float tag) {
    for (size_t i = 0; i < names.size(); ++i) ch.push_back(coded("ViewLayer." + layer + "." + names[i], tag + static_cast<float>(i)));
  };
  group("Combined", {"R", "G", "B", "A"}, 10);
  group("Denoising Albedo", {"R", "G", "B"}, 20);
  group("Diffuse Direct", {"R", "G", "B"}, 30);
  group("CryptoObject00", {"R", "G", "B", "A"}, 40);
  group("Extra", {"c1", "c2", "c3", "c4", "c5"}, 50);
  write_fixture_exr(f, {part(6, 4, ch)});
  const AovStack s = load_aov_stack({f});
  ASSERT_EQ(s.convention, "Blender Cycles");
  const auto layers = other_layers(s);
  std::vector<std::string> names;
  for (const auto& l : layers) names.push_back(l.name);
  // In the file's order (OpenEXR keeps channels sorted by name).
  const std::vector<std::string> expected = {"ViewLayer.Combined.A", "ViewLayer.CryptoObject00",
                                             "ViewLayer.CryptoObject00.A", "ViewLayer.Diffuse Direct",
                                             "ViewLayer.Extra (c1,c2,c3)", "ViewLayer.Extra (c4,c5)"};
  ASSERT_EQ(names, expected);
  const std::vector<std::pair<size_t, float>> first_tag = {{0, 13}, {1, 40}, {2, 43}, {3, 30}, {4, 50}, {5, 53}};
  for (const auto& [i, tag] : first_tag) {
    const Image img = read_other_layer(layers[i], s);
    ASSERT_EQ(img.width(), 6);
    ASSERT_EQ(img.height(), 4);
    ASSERT_EQ(img.channels(), static_cast<int>(layers[i].channels.size()));
    for (int c = 0; c < img.channels(); ++c)
      for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 6; ++x)
          ASSERT_FLOAT_EQ(img.at(x, y, c), code(tag + static_cast<float>(c), x, y)) << names[i] << " c" << c;
  }
}

// A layer in another part of a multipart file, with a smaller data window, lands where it lies (0 elsewhere); a
// layer of a file that is gone is an input error naming the file.
TEST(OtherLayers, APartsLayerIsPlacedOnTheGridAndAMissingFileIsNamed) {
  TempDir tmp;
  const auto f = tmp / "parts.exr";
  FixturePart beauty = part(6, 4, {coded("R", 10), coded("G", 11), coded("B", 12)});
  beauty.name = "rgba";
  FixturePart extra = part(3, 2, {coded("R", 60), coded("G", 61), coded("B", 62)});
  extra.name = "specular";
  extra.x = 2;
  extra.y = 1;
  extra.full_width = 6;
  extra.full_height = 4;
  write_fixture_exr(f, {beauty, extra});
  const AovStack s = load_aov_stack({f});
  const auto layers = other_layers(s);
  ASSERT_EQ(layers.size(), 1u);
  EXPECT_EQ(layers[0].name, "specular");
  const Image img = read_other_layer(layers[0], s);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 6; ++x) {
      const bool inside = x >= 2 && x < 5 && y >= 1 && y < 3;
      EXPECT_FLOAT_EQ(img.at(x, y, 1), inside ? code(61, x, y) : 0.0f) << x << "," << y;
    }
  std::filesystem::remove(f);
  const std::string message = error_of([&] { read_other_layer(layers[0], s); });
  EXPECT_NE(message.find("parts.exr"), std::string::npos) << message;
  EXPECT_TRUE(other_layers(s).empty()) << "a file that is gone lists no layers";
}

// Every layer of pbrt's signature is needed: an Arnold render with a position AOV stays Arnold's.
TEST(AovConventions, ArnoldWithPositionAndAlbedoIsNotPbrt) {
  TempDir tmp;
  const auto f = tmp / "arnold_p.exr";
  write_fixture_exr(f, {part(5, 3, {coded("R", 10), coded("G", 11), coded("B", 12), coded("N.X", 20),
                                    coded("N.Y", 21), coded("N.Z", 22), coded("P.X", 60), coded("P.Y", 61),
                                    coded("P.Z", 62), coded("albedo.R", 30), coded("albedo.G", 31),
                                    coded("albedo.B", 32), coded("Z", 40)})});
  const AovStack s = load_aov_stack({f});
  EXPECT_EQ(s.convention, "Arnold");
  expect_coded(s, AovRole::Depth, 40);
  EXPECT_EQ(s.normal_space, NormalSpace::World);
}

// The OpenEXR worldToCamera attribute is for row vectors (p_cam = p_world M); pbrt-v4 writes its own
// column-vector matrix there. Both must give the same camera: ours is column-vector, looking down -z.
TEST(AovConventions, WorldToCameraRowOrColumnVectors) {
  // A camera at (1, 2, 3) turned 90 degrees about y, in the header's left-handed, +z-forward camera space:
  // p_cam = R (p - t) with R mapping world x to camera z.
  const double r[3][3] = {{0, 0, -1}, {0, 1, 0}, {1, 0, 0}};
  const double t[3] = {1, 2, 3};
  std::array<float, 16> column{}, row{};
  for (int i = 0; i < 3; ++i) {
    double tr = 0;
    for (int j = 0; j < 3; ++j) {
      column[static_cast<size_t>(i * 4 + j)] = static_cast<float>(r[i][j]);
      tr += r[i][j] * t[j];
    }
    column[static_cast<size_t>(i * 4 + 3)] = static_cast<float>(-tr);
  }
  column[15] = 1;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) row[static_cast<size_t>(i * 4 + j)] = column[static_cast<size_t>(j * 4 + i)];

  TempDir tmp;
  for (const bool pbrt : {false, true}) {
    const auto f = tmp / (pbrt ? "column.exr" : "row.exr");
    FixturePart p = part(2, 2, {coded("R", 10), coded("G", 11), coded("B", 12)});
    p.matrix_attributes = {{"worldToCamera", pbrt ? column : row}};
    write_fixture_exr(f, {p});
    const AovStack s = load_aov_stack({f});
    ASSERT_TRUE(s.world_to_camera.has_value()) << f;
    // The world point (2, 2, 3) is 1 ahead of the camera along its view axis: (0, 0, -1) in ours.
    const double pw[4] = {2, 2, 3, 1};
    double pc[3] = {0, 0, 0};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 4; ++j) pc[i] += (*s.world_to_camera)[static_cast<size_t>(i * 4 + j)] * pw[j];
    EXPECT_NEAR(pc[0], 0, 1e-6) << f;
    EXPECT_NEAR(pc[1], 0, 1e-6) << f;
    EXPECT_NEAR(pc[2], -1, 1e-6) << f;
    EXPECT_EQ(std::any_of(s.notes.begin(), s.notes.end(),
                          [](const std::string& n) { return n.find("column vectors") != std::string::npos; }),
              pbrt)
        << f;
  }
}

TEST(AovConventions, RenderMan) {
  TempDir tmp;
  const auto f = tmp / "prman.exr";
  write_fixture_exr(f, {part(4, 6, {coded("Ci.r", 10), coded("Ci.g", 11), coded("Ci.b", 12), constant_channel("a", 1),
                                    coded("albedo.r", 30), coded("albedo.g", 31), coded("albedo.b", 32),
                                    coded("normal.x", 20), coded("normal.y", 21), coded("normal.z", 22),
                                    coded("zfiltered.r", 40), coded("mse.r", 50), coded("mse.g", 51), coded("mse.b", 52),
                                    coded("diffuse.r", 90), coded("diffuse.g", 91), coded("diffuse.b", 92)})});
  const AovStack s = load_aov_stack({f});
  EXPECT_EQ(s.convention, "RenderMan");
  expect_coded(s, AovRole::Color, 10);
  expect_coded(s, AovRole::Albedo, 30);  // RenderMan's diffuse is lighting, not albedo
  expect_coded(s, AovRole::Normal, 20);
  expect_coded(s, AovRole::Depth, 40);
  expect_coded(s, AovRole::Variance, 50);
}

TEST(AovConventions, VRayLeadingDotsAndColourNames) {
  TempDir tmp;
  const auto f = tmp / "vray.exr";
  write_fixture_exr(f, {part(6, 2, {coded(".R", 10), coded(".G", 11), coded(".B", 12),
                                    coded("diffuse.red", 30), coded("diffuse.green", 31), coded("diffuse.blue", 32),
                                    coded("bump_normals.x", 20), coded("bump_normals.y", 21), coded("bump_normals.z", 22)})});
  const AovStack s = load_aov_stack({f});
  EXPECT_EQ(s.convention, "V-Ray");
  expect_coded(s, AovRole::Color, 10);
  expect_coded(s, AovRole::Albedo, 30);
  expect_coded(s, AovRole::Normal, 20);
  EXPECT_FALSE(s.depth.has_value());
}

TEST(AovConventions, PlainLayersWithReference) {
  TempDir tmp;
  const auto f = tmp / "plain.exr";
  write_fixture_exr(f, {part(1, 1, {coded("R", 10), coded("G", 11), coded("B", 12),
                                    coded("albedo.R", 30), coded("albedo.G", 31), coded("albedo.B", 32),
                                    coded("normal.X", 20), coded("normal.Y", 21), coded("normal.Z", 22),
                                    coded("depth.Z", 40), coded("reference.R", 60), coded("reference.G", 61),
                                    coded("reference.B", 62)})});
  const AovStack s = load_aov_stack({f});
  EXPECT_EQ(s.convention, "plain R,G,B with named layers");
  EXPECT_EQ(s.width(), 1);
  for (auto [role, tag] : std::vector<std::pair<AovRole, float>>{{AovRole::Color, 10}, {AovRole::Albedo, 30},
                                                                 {AovRole::Normal, 20}, {AovRole::Depth, 40},
                                                                 {AovRole::Reference, 60}})
    expect_coded(s, role, tag);
  EXPECT_EQ(s.normal_space, NormalSpace::Unknown);
  LoadOptions o;
  o.normal_space = NormalSpace::World;
  EXPECT_EQ(load_aov_stack({f}, o).normal_space, NormalSpace::World);
}

// Mitsuba 3's aov integrator names its layers as told; its documentation's names: "nn" (sh_normal), "dd.y" (depth).
TEST(AovConventions, PlainWithMitsubaAovNames) {
  TempDir tmp;
  const auto f = tmp / "mitsuba.exr";
  write_fixture_exr(f, {part(2, 2, {coded("R", 10), coded("G", 11), coded("B", 12), constant_channel("A", 1),
                                    coded("albedo.R", 30), coded("albedo.G", 31), coded("albedo.B", 32),
                                    coded("nn.X", 20), coded("nn.Y", 21), coded("nn.Z", 22), coded("dd.y", 40)})});
  const AovStack s = load_aov_stack({f});
  EXPECT_EQ(s.convention, "plain R,G,B with named layers");
  for (auto [role, tag] : std::vector<std::pair<AovRole, float>>{
           {AovRole::Color, 10}, {AovRole::Albedo, 30}, {AovRole::Normal, 20}, {AovRole::Depth, 40}})
    expect_coded(s, role, tag);
}

TEST(AovConventions, MultipartWithUnqualifiedChannelNames) {
  TempDir tmp;
  const auto f = tmp / "multipart.exr";
  FixturePart rgba = part(7, 13, {coded("R", 10, true), coded("G", 11, true), coded("B", 12, true)});
  rgba.name = "rgba";
  FixturePart albedo = part(7, 13, {coded("R", 30), coded("G", 31), coded("B", 32)});
  albedo.name = "albedo";
  FixturePart normal = part(7, 13, {coded("normal.X", 20), coded("normal.Y", 21), coded("normal.Z", 22)});
  normal.name = "normal";
  FixturePart depth = part(7, 13, {coded("Z", 40)});
  depth.name = "depth";
  write_fixture_exr(f, {rgba, albedo, normal, depth});
  const AovStack s = load_aov_stack({f});
  EXPECT_EQ(s.albedo->source.subimage, 1);
  EXPECT_EQ(s.albedo->source.channels.front(), "albedo.R");
  expect_coded(s, AovRole::Albedo, 30);
  expect_coded(s, AovRole::Normal, 20);
  expect_coded(s, AovRole::Depth, 40);
  EXPECT_EQ(s.color.image.at(6, 12, 2), as_half(code(12, 6, 12)));
}

TEST(AovConventions, OidnFileSet) {
  TempDir tmp;
  auto rgb = [](float tag) { return std::vector<FixtureChannel>{coded("R", tag), coded("G", tag + 1), coded("B", tag + 2)}; };
  write_fixture_exr(tmp / "kitchen_0016spp.hdr.exr", {part(9, 4, rgb(10))});
  write_fixture_exr(tmp / "kitchen_0016spp.alb.exr", {part(9, 4, rgb(30))});
  write_fixture_exr(tmp / "kitchen_0016spp.nrm.exr", {part(9, 4, rgb(20))});
  write_fixture_exr(tmp / "kitchen_ref.hdr.exr", {part(9, 4, rgb(60))});
  for (const auto& input : {tmp.path(), tmp / "kitchen_0016spp.hdr.exr"}) {
    const AovStack s = load_aov_stack({input});
    EXPECT_EQ(s.convention, "OIDN data set");
    expect_coded(s, AovRole::Color, 10);
    expect_coded(s, AovRole::Albedo, 30);
    expect_coded(s, AovRole::Normal, 20);
    expect_coded(s, AovRole::Reference, 60);
    EXPECT_FALSE(s.depth.has_value());
  }
}

// The data sets' layout (and the Cycles starter set's): noisy_a.exr with reference.exr beside it. The viewer and
// eval find the reference without -r, and say so; one of another size is left out, with a note.
TEST(AovConventions, CyclesReferenceBesideTheRender) {
  const auto scene = testing::shared_dataset("cycles-starter/s105");
  RESIDUE_REQUIRE_SHARED(scene);
  TempDir tmp;
  std::filesystem::copy_file(scene / "noisy_a.exr", tmp / "noisy_a.exr");
  std::filesystem::copy_file(scene / "reference.exr", tmp / "reference.exr");
  const AovStack s = load_aov_stack({tmp / "noisy_a.exr"});
  ASSERT_TRUE(s.reference);
  EXPECT_EQ(s.reference->source.file, (tmp / "reference.exr").string());
  const AovStack direct = load_aov_stack({scene / "reference.exr"});
  EXPECT_EQ(s.reference->image.at(100, 100, 1), direct.color.image.at(100, 100, 1));
  EXPECT_NE(std::find_if(s.notes.begin(), s.notes.end(),
                         [](const std::string& n) { return n.find("beside the render") != std::string::npos; }),
            s.notes.end());
  LoadOptions no_ref;
  no_ref.load_reference = false;
  EXPECT_FALSE(load_aov_stack({tmp / "noisy_a.exr"}, no_ref).reference);
  // Another size: not used.
  std::filesystem::remove(tmp / "reference.exr");
  write_fixture_exr(tmp / "reference.exr", {part(8, 8, {coded("R", 1), coded("G", 2), coded("B", 3)})});
  const AovStack other = load_aov_stack({tmp / "noisy_a.exr"});
  EXPECT_FALSE(other.reference);
  EXPECT_NE(std::find_if(other.notes.begin(), other.notes.end(),
                         [](const std::string& n) { return n.find("has another size") != std::string::npos; }),
            other.notes.end());
}

TEST(AovConventions, FilesNamedByRole) {
  TempDir tmp;
  write_fixture_exr(tmp / "beauty.exr", {part(3, 3, {coded("R", 10), coded("G", 11), coded("B", 12)})});
  write_fixture_exr(tmp / "shot_albedo.exr", {part(3, 3, {coded("R", 30), coded("G", 31), coded("B", 32)})});
  write_fixture_exr(tmp / "shot_depth.exr", {part(3, 3, {coded("Y", 40)})});
  const AovStack s = load_aov_stack({tmp / "shot_depth.exr", tmp / "beauty.exr", tmp / "shot_albedo.exr"});
  expect_coded(s, AovRole::Color, 10);
  expect_coded(s, AovRole::Albedo, 30);
  expect_coded(s, AovRole::Depth, 40);
}

// --- windows, non-finite values, sizes ---------------------------------------------------------------------

TEST(AovWindows, DataWindowDiffersFromDisplayWindow) {
  TempDir tmp;
  FixturePart colour = part(7, 13, {coded("R", 10), coded("G", 11), coded("B", 12)});
  colour.x = 5;
  colour.y = 3;
  colour.full_width = 20;
  colour.full_height = 20;
  // The albedo file covers the whole display window; only the colour's data window is taken from it.
  FixturePart albedo = part(20, 20, {coded("R", 30), coded("G", 31), coded("B", 32)});
  write_fixture_exr(tmp / "color.exr", {colour});
  write_fixture_exr(tmp / "albedo.exr", {albedo});
  const AovStack s = load_aov_stack({tmp / "color.exr"});
  EXPECT_EQ(s.data_window, (Rect{5, 3, 7, 13}));
  EXPECT_EQ(s.display_width, 20);
  EXPECT_EQ(s.width(), 7);
  EXPECT_EQ(s.color.image.at(0, 0, 0), code(10, 5, 3));
  EXPECT_EQ(s.albedo->image.at(0, 0, 0), code(30, 5, 3));
  EXPECT_EQ(s.albedo->image.at(6, 12, 2), code(32, 11, 15));
  EXPECT_EQ(s.albedo->uncovered_pixels, 0);
}

TEST(AovWindows, PartlyCoveredAovIsZeroFilledAndNoted) {
  TempDir tmp;
  FixturePart colour = part(10, 10, {coded("R", 10), coded("G", 11), coded("B", 12)});
  FixturePart albedo = part(4, 10, {coded("R", 30), coded("G", 31), coded("B", 32)});
  albedo.full_width = albedo.full_height = 10;
  write_fixture_exr(tmp / "color.exr", {colour});
  write_fixture_exr(tmp / "albedo.exr", {albedo});
  const AovStack s = load_aov_stack({tmp / "color.exr"});
  EXPECT_EQ(s.albedo->uncovered_pixels, 60);
  EXPECT_EQ(s.albedo->image.at(8, 2, 0), 0.0f);
  EXPECT_EQ(s.albedo->image.at(3, 2, 0), code(30, 3, 2));
  EXPECT_FALSE(s.notes.empty());
}

TEST(AovNonFinite, NanAndInfAreCountedNotFatal) {
  TempDir tmp;
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  auto bad = [&](int x, int y) { return x == 1 && y == 1 ? nan : (x == 2 && y == 0 ? inf : 0.5f); };
  write_fixture_exr(tmp / "bad.exr", {part(4, 3, {{"R", true, bad}, {"G", false, bad}, {"B", false, bad},
                                                  {"albedo.R", false, bad}, {"albedo.G", false, bad},
                                                  {"albedo.B", false, bad},
                                                  {"depth.Z", false, [&](int x, int) { return x == 0 ? inf : 1.0f; }}})});
  const AovStack s = load_aov_stack({tmp / "bad.exr"});
  EXPECT_EQ(s.color.non_finite.nan, 3);
  EXPECT_EQ(s.color.non_finite.inf, 3);
  EXPECT_EQ(s.albedo->non_finite.total(), 6);
  EXPECT_TRUE(std::isnan(s.color.image.at(1, 1, 0)));
  // +Inf depth means "no hit": background, not an error.
  EXPECT_EQ(s.depth->non_finite.total(), 0);
  EXPECT_EQ(s.depth_background_pixels, 3);
}

TEST(AovLarge, SixtyFourBitOffsets) {
  // 16K x 16K x 9 channels has more values than a 32-bit int can index.
  Image probe;  // offsets are pure arithmetic: no allocation needed
  const int64_t w = 16384, h = 16384, c = 9;
  const int64_t last = (h - 1) * w * c + (w - 1) * c + 8;
  EXPECT_GT(last, int64_t{std::numeric_limits<int32_t>::max()});
  Image row_image(w, 2, 9);
  EXPECT_EQ(row_image.offset(w - 1, 1, 8), 2 * w * 9 - 1);
}

TEST(AovLarge, WideImageLoads) {
  // A 16384-pixel-wide image exercises the banded reader across many rows of bands.
  TempDir tmp;
  const int w = 16384, h = 130;
  write_fixture_exr(tmp / "wide.exr", {part(w, h, {coded("R", 1, true), coded("G", 2), coded("B", 3)})});
  const AovStack s = load_aov_stack({tmp / "wide.exr"});
  EXPECT_EQ(s.width(), w);
  EXPECT_EQ(s.height(), h);
  EXPECT_EQ(s.color.image.at(w - 1, h - 1, 2), code(3, w - 1, h - 1));
  EXPECT_EQ(s.color.image.at(w - 1, 64, 1), code(2, w - 1, 64));
}

TEST(AovLarge, SixteenKSquareLoads) {
  // A real 16384 x 16384 half RGB EXR (3.2 GB as floats once loaded), written band by band to keep the
  // test's own memory small. The pattern marks rows and columns so misplaced bands would show.
  TempDir tmp;
  const int n = 16384;
  const auto path = (tmp / "16k.exr").string();
  {
    OIIO::ImageSpec spec(n, n, 3, OIIO::TypeHalf);
    spec.attribute("compression", "zip");
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out && out->open(path, spec));
    const int band = 256;
    std::vector<float> rows(static_cast<size_t>(band) * n * 3);
    for (int y0 = 0; y0 < n; y0 += band) {
      for (int y = 0; y < band; ++y)
        for (int x = 0; x < n; ++x) {
          float* px = &rows[(static_cast<size_t>(y) * n + static_cast<size_t>(x)) * 3];
          px[0] = static_cast<float>((y0 + y) % 1024);
          px[1] = static_cast<float>(x % 1024);
          px[2] = 0.5f;
        }
      ASSERT_TRUE(out->write_scanlines(y0, y0 + band, 0, OIIO::TypeFloat, rows.data()));
    }
    out->close();
  }
  const AovStack s = load_aov_stack({path});
  ASSERT_EQ(s.width(), n);
  ASSERT_EQ(s.height(), n);
  for (int64_t y : {0, 1, 1023, 1024, 8191, 16383})
    for (int64_t x : {0, 5, 1023, 16383}) {
      EXPECT_EQ(s.color.image.at(x, y, 0), static_cast<float>(y % 1024)) << x << "," << y;
      EXPECT_EQ(s.color.image.at(x, y, 1), static_cast<float>(x % 1024)) << x << "," << y;
    }
  EXPECT_EQ(s.color.non_finite.total(), 0);
}

// --- explicit mappings -------------------------------------------------------------------------------------

TEST(AovMapping, FlagsMapOddNamesAndOtherFiles) {
  TempDir tmp;
  write_fixture_exr(tmp / "odd.exr", {part(5, 5, {coded("beauty_r", 10), coded("beauty_g", 11), coded("beauty_b", 12),
                                                  coded("nn.u", 20), coded("nn.v", 21), coded("nn.w", 22)})});
  write_fixture_exr(tmp / "zz.exr", {part(5, 5, {coded("dist", 40)})});
  ChannelMapping m;
  m.add_flag("color=beauty_r,beauty_g,beauty_b");
  m.add_flag("normal=nn");
  m.add_flag("depth=" + (tmp / "zz.exr").string());
  LoadOptions o;
  o.mapping = m;
  const AovStack s = load_aov_stack({tmp / "odd.exr"}, o);
  expect_coded(s, AovRole::Color, 10);
  expect_coded(s, AovRole::Normal, 20);
  expect_coded(s, AovRole::Depth, 40);
}

TEST(AovMapping, JsonFileWithRelativePaths) {
  TempDir tmp;
  write_fixture_exr(tmp / "main.exr", {part(2, 3, {coded("R", 10), coded("G", 11), coded("B", 12),
                                                   coded("base.R", 30), coded("base.G", 31), coded("base.B", 32)})});
  write_fixture_exr(tmp / "n.exr", {part(2, 3, {coded("N.X", 20), coded("N.Y", 21), coded("N.Z", 22)})});
  std::ofstream(tmp / "map.json") << R"({"albedo": {"channels": ["base.R", "base.G", "base.B"]},
      "normal": {"file": "n.exr", "channels": ["N.X", "N.Y", "N.Z"], "space": "world"}})";
  LoadOptions o;
  o.mapping = ChannelMapping::from_json_file(tmp / "map.json");
  const AovStack s = load_aov_stack({tmp / "main.exr"}, o);
  expect_coded(s, AovRole::Albedo, 30);
  expect_coded(s, AovRole::Normal, 20);
  EXPECT_EQ(s.normal_space, NormalSpace::World);
}

// --- errors name the file, the channels found and the channels expected ------------------------------------

TEST(AovErrors, MissingFile) {
  ErrorKind kind{};
  const std::string msg = error_of([] { load_aov_stack({"/nonexistent/render.exr"}); }, &kind);
  EXPECT_EQ(kind, ErrorKind::Input);
  EXPECT_NE(msg.find("/nonexistent/render.exr"), std::string::npos) << msg;
}

TEST(AovErrors, NotAnImage) {
  TempDir tmp;
  std::ofstream(tmp / "junk.exr") << "this is not an EXR";
  const std::string msg = error_of([&] { load_aov_stack({tmp / "junk.exr"}); });
  EXPECT_NE(msg.find("junk.exr"), std::string::npos) << msg;
}

TEST(AovErrors, NoColourNamesFileFoundAndExpected) {
  TempDir tmp;
  write_fixture_exr(tmp / "nocolour.exr", {part(2, 2, {coded("foo.X", 1), coded("bar", 2)})});
  ErrorKind kind{};
  const std::string msg = error_of([&] { load_aov_stack({tmp / "nocolour.exr"}); }, &kind);
  EXPECT_EQ(kind, ErrorKind::Input);
  EXPECT_NE(msg.find("nocolour.exr"), std::string::npos) << msg;
  EXPECT_NE(msg.find("foo.X"), std::string::npos) << "lists the channels found: " << msg;
  EXPECT_NE(msg.find("R,G,B"), std::string::npos) << "says what was expected: " << msg;
}

TEST(AovErrors, MappedChannelMissing) {
  TempDir tmp;
  write_fixture_exr(tmp / "a.exr", {part(2, 2, {coded("R", 1), coded("G", 2), coded("B", 3)})});
  LoadOptions o;
  o.mapping.add_flag("albedo=alb.R,alb.G,alb.B");
  ErrorKind kind{};
  const std::string msg = error_of([&] { load_aov_stack({tmp / "a.exr"}, o); }, &kind);
  EXPECT_EQ(kind, ErrorKind::Mapping);
  EXPECT_NE(msg.find("alb.R"), std::string::npos) << msg;
  EXPECT_NE(msg.find("a.exr"), std::string::npos) << msg;
  EXPECT_NE(msg.find("R, G, B"), std::string::npos) << "lists what the file has: " << msg;
}

TEST(AovErrors, WrongChannelCountInMapping) {
  TempDir tmp;
  write_fixture_exr(tmp / "a.exr", {part(2, 2, {coded("R", 1), coded("G", 2), coded("B", 3)})});
  LoadOptions o;
  o.mapping.add_flag("normal=R,G");
  const std::string msg = error_of([&] { load_aov_stack({tmp / "a.exr"}, o); });
  EXPECT_NE(msg.find("2 channels"), std::string::npos) << msg;
}

TEST(AovErrors, SizeMismatchNamesBothFiles) {
  TempDir tmp;
  write_fixture_exr(tmp / "color.exr", {part(8, 8, {coded("R", 1), coded("G", 2), coded("B", 3)})});
  write_fixture_exr(tmp / "albedo.exr", {part(4, 4, {coded("R", 1), coded("G", 2), coded("B", 3)})});
  ErrorKind kind{};
  const std::string msg = error_of([&] { load_aov_stack({tmp / "color.exr"}); }, &kind);
  EXPECT_EQ(kind, ErrorKind::Input);
  EXPECT_NE(msg.find("albedo.exr"), std::string::npos) << msg;
  EXPECT_NE(msg.find("4x4"), std::string::npos) << msg;
  EXPECT_NE(msg.find("8x8"), std::string::npos) << msg;
}

TEST(AovErrors, BadMappingFlagsAndFiles) {
  ChannelMapping m;
  EXPECT_NE(error_of([&] { m.add_flag("albedo"); }).find("ROLE="), std::string::npos);
  EXPECT_NE(error_of([&] { m.add_flag("glossiness=a,b,c"); }).find("unknown AOV \"glossiness\""), std::string::npos);
  TempDir tmp;
  std::ofstream(tmp / "bad.json") << "{ not json";
  EXPECT_NE(error_of([&] { ChannelMapping::from_json_file(tmp / "bad.json"); }).find("bad.json"), std::string::npos);
  std::ofstream(tmp / "badkey.json") << R"({"normal": {"file": "n.exr", "colour": 1}})";
  EXPECT_NE(error_of([&] { ChannelMapping::from_json_file(tmp / "badkey.json"); }).find("\"colour\""),
            std::string::npos);
  std::ofstream(tmp / "badspace.json") << R"({"normal": {"space": "tangent"}})";
  EXPECT_NE(error_of([&] { ChannelMapping::from_json_file(tmp / "badspace.json"); }).find("space"), std::string::npos);
}

TEST(AovErrors, FolderWithoutColour) {
  TempDir tmp;
  const std::string msg = error_of([&] { load_aov_stack({tmp.path()}); });
  // Every file-set convention of the registry says what it looks for.
  for (const auto& convention : file_set_conventions())
    EXPECT_NE(msg.find(convention->colour_file_pattern()), std::string::npos) << msg;
  EXPECT_NE(msg.find("color.exr"), std::string::npos) << msg;
}

TEST(AovErrors, FolderWithColourFilesOfTwoConventionsNamesBoth) {
  TempDir tmp;
  const auto rgb = std::vector<FixtureChannel>{coded("R", 10), coded("G", 11), coded("B", 12)};
  write_fixture_exr(tmp / "color.exr", {part(4, 4, rgb)});
  write_fixture_exr(tmp / "kitchen_0016spp.hdr.exr", {part(4, 4, rgb)});
  const std::string msg = error_of([&] { load_aov_stack({tmp.path()}); });
  EXPECT_NE(msg.find("several colour files"), std::string::npos) << msg;
  EXPECT_NE(msg.find("color.exr"), std::string::npos) << msg;
  EXPECT_NE(msg.find("kitchen_0016spp.hdr.exr"), std::string::npos) << msg;
  // Given the file itself, each finds its own siblings.
  write_fixture_exr(tmp / "albedo.exr", {part(4, 4, {coded("R", 30), coded("G", 31), coded("B", 32)})});
  write_fixture_exr(tmp / "kitchen_0016spp.alb.exr", {part(4, 4, {coded("R", 50), coded("G", 51), coded("B", 52)})});
  const AovStack oidn = load_aov_stack({tmp / "kitchen_0016spp.hdr.exr"});
  EXPECT_EQ(oidn.convention, "OIDN data set");
  expect_coded(oidn, AovRole::Albedo, 50);
  const AovStack tungsten = load_aov_stack({tmp / "color.exr"});
  EXPECT_EQ(tungsten.convention, "Tungsten file set");
  expect_coded(tungsten, AovRole::Albedo, 30);
}

}  // namespace
}  // namespace residue

namespace residue {
namespace {

// Writes a 4x2 RGB image of one value per channel, as `type`, optionally tagged with a colour space.
void write_flat(const std::filesystem::path& path, OIIO::TypeDesc type, const float rgb[3], const char* colorspace) {
  OIIO::ImageSpec spec(4, 2, 3, type);
  if (colorspace) spec.attribute("oiio:ColorSpace", colorspace);
  std::vector<float> px(4 * 2 * 3);
  for (size_t i = 0; i < px.size(); ++i) px[i] = rgb[i % 3];
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out && out->open(path.string(), spec));
  ASSERT_TRUE(out->write_image(OIIO::TypeFloat, px.data()));
  out->close();
}

TEST(AovEncoding, PngColourIsDecodedFromSrgbToLinear) {
  TempDir dir;
  // 8-bit sRGB 188/255 is linear 0.5029 (the sRGB curve), 0 stays 0, 255 stays 1.
  const float rgb[3] = {188.0f / 255.0f, 0.0f, 1.0f};
  write_flat(dir.path() / "render.png", OIIO::TypeDesc::UINT8, rgb, nullptr);
  const AovStack s = load_aov_stack({dir.path() / "render.png"});
  const double expected = std::pow((188.0 / 255.0 + 0.055) / 1.055, 2.4);  // written out here, not the loader's
  EXPECT_NEAR(s.color.image.at(1, 1, 0), expected, 1e-6);
  EXPECT_EQ(s.color.image.at(1, 1, 1), 0.0f);
  EXPECT_NEAR(s.color.image.at(1, 1, 2), 1.0, 1e-6);
  const bool noted = std::any_of(s.notes.begin(), s.notes.end(),
                                 [](const std::string& n) { return n.find("decoded to linear") != std::string::npos; });
  EXPECT_TRUE(noted);
}

TEST(AovEncoding, LinearFloatTiffIsUsedAsStored) {
  TempDir dir;
  const float rgb[3] = {0.25f, 3.5f, 0.0f};
  write_flat(dir.path() / "render.tif", OIIO::TypeDesc::FLOAT, rgb, "linear");
  const AovStack s = load_aov_stack({dir.path() / "render.tif"});
  EXPECT_EQ(s.color.image.at(0, 0, 0), 0.25f);
  EXPECT_EQ(s.color.image.at(0, 0, 1), 3.5f);
}

}  // namespace
}  // namespace residue
