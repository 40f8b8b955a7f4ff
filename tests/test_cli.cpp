// residue-cli end to end: real renders in, tables/JSON/maps out, exit codes for bad input.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

#include "core/nn/backend.h"
#include "support/exr_fixture.h"
#include "support/test_support.h"

namespace residue {
namespace {

using testing::run_cli;
using testing::TempDir;

nlohmann::json eval_json(const std::vector<std::string>& args) {
  std::string out;
  std::vector<std::string> full = {"eval", "--json"};
  full.insert(full.end(), args.begin(), args.end());
  const int rc = run_cli(full, &out);
  EXPECT_EQ(rc, 0) << out;
  return nlohmann::json::parse(out);
}

std::string read_file(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(Cli, EvalMatchesSceneJsonOnEveryStarterScene) {
  const auto root = testing::shared_dataset("cycles-starter");
  RESIDUE_REQUIRE_SHARED(root);
  int scenes = 0;
  for (const auto& entry : std::filesystem::directory_iterator(root)) {
    if (!entry.is_directory()) continue;
    const auto scene = nlohmann::json::parse(read_file(entry.path() / "scene.json"));
    const double expected = scene["metrics"]["relmse_noisy_a"].get<double>();
    const auto j = eval_json({(entry.path() / "noisy_a.exr").string(), "--reference",
                              (entry.path() / "reference.exr").string()});
    const double got = j["rows"][0]["relmse"].get<double>();
    // The brief asks for 3 significant digits; the computation is the same, so it agrees far better.
    EXPECT_NEAR(got, expected, 1e-9 * expected) << entry.path();
    ++scenes;
  }
  EXPECT_GE(scenes, 60);
}

TEST(Cli, EvalTableOnTungstenWithDenoised) {
  const auto dir = testing::shared_dataset("tungsten-example/cornell-box");
  RESIDUE_REQUIRE_SHARED(dir);
  std::string out;
  ASSERT_EQ(run_cli({"eval", dir.string(), "--denoised", (dir / "nfor.exr").string()}, &out), 0) << out;
  EXPECT_NE(out.find("noisy"), std::string::npos) << out;
  EXPECT_NE(out.find("denoised"), std::string::npos) << out;
  EXPECT_NE(out.find("eps = 0.01"), std::string::npos) << "the formula is printed with the table: " << out;
  const auto j = eval_json({dir.string(), "--denoised", (dir / "nfor.exr").string()});
  // NFOR is a good denoiser: far lower error than the noisy input.
  EXPECT_LT(j["rows"][1]["relmse"].get<double>(), 0.1 * j["rows"][0]["relmse"].get<double>());
  EXPECT_GT(j["rows"][1]["ssim"].get<double>(), j["rows"][0]["ssim"].get<double>());
}

// eval scores HDR-FLIP beside relMSE and SSIM: on the Cornell box, NVIDIA's reference code gives 0.1370818 for the
// noisy render and 0.0572303 for NFOR (../shared/reference/flip/expected.json), and its tool's magma map of NFOR's
// error is the one eval writes, to the colour table's rounding; --flip off leaves it out.
TEST(Cli, EvalScoresHdrFlipAsNvidiasCodeDoes) {
  const auto dir = testing::shared_dataset("tungsten-example/cornell-box");
  RESIDUE_REQUIRE_SHARED(dir);
  TempDir tmp;
  const auto j = eval_json({(dir / "color.exr").string(), "-r", (dir / "reference.exr").string(), "--denoised",
                            (dir / "nfor.exr").string(), "--maps-dir", tmp.path().string()});
  EXPECT_NEAR(j["rows"][0]["hdr_flip"].get<double>(), 0.1370818, 1e-5);
  EXPECT_NEAR(j["rows"][1]["hdr_flip"].get<double>(), 0.0572303, 1e-5);
  EXPECT_EQ(j["flip"]["exposures"]["count"], 8);
  const std::filesystem::path official =
      std::filesystem::path(RESIDUE_SHARED_DIR) / "reference/flip/maps/cornell-box_nfor_hdrflip_magma.png";
  if (std::filesystem::exists(official)) {
    OIIO::ImageBuf ours((tmp / "denoised_flip.png").string()), theirs(official.string());
    const auto diff = OIIO::ImageBufAlgo::compare(ours, theirs, 2.5f / 255, 2.5f / 255);
    EXPECT_EQ(diff.nfail, 0u) << "largest difference " << diff.maxerror * 255 << " codes";
  }
  const auto off = eval_json({(dir / "color.exr").string(), "-r", (dir / "reference.exr").string(), "--flip", "off"});
  EXPECT_TRUE(off["rows"][0]["hdr_flip"].is_null());
  EXPECT_TRUE(off["flip"].is_null());
}

// libgomp reads OMP_WAIT_POLICY once, when it is loaded; the program sets it before that (core/util/openmp_env.h)
// without starting a second time: OMP_DISPLAY_ENV makes libgomp print its settings once per process start.
TEST(Cli, OpenMpWaitsPassivelyFromASingleStart) {
#if defined(RESIDUE_HAVE_ONEDNN)
  std::string text;
  ASSERT_EQ(testing::run_program("/usr/bin/env", {"-u", "OMP_WAIT_POLICY", "OMP_DISPLAY_ENV=true", RESIDUE_CLI_PATH,
                                                  "--version"}, &text), 0) << text;
  size_t starts = 0;
  for (size_t at = text.find("OPENMP DISPLAY ENVIRONMENT BEGIN"); at != std::string::npos;
       at = text.find("OPENMP DISPLAY ENVIRONMENT BEGIN", at + 1))
    ++starts;
  EXPECT_EQ(starts, 1u) << text;
  EXPECT_NE(text.find("OMP_WAIT_POLICY = 'PASSIVE'"), std::string::npos) << text;
  ASSERT_EQ(testing::run_program("/usr/bin/env", {"OMP_WAIT_POLICY=active", "OMP_DISPLAY_ENV=true", RESIDUE_CLI_PATH,
                                                  "--version"}, &text), 0) << text;
  EXPECT_NE(text.find("OMP_WAIT_POLICY = 'ACTIVE'"), std::string::npos) << "the user's own setting is kept: " << text;
#else
  GTEST_SKIP() << "built without oneDNN: nothing runs on OpenMP";
#endif
}

// bench names the CPU its figures come from and times the cold first run (primitive creation, weight reorders,
// fresh arena pages) apart from the warm runs that reuse the backend, which are the ones it rates.
TEST(Cli, BenchNamesTheCpuAndSeparatesTheColdRun) {
  std::string out;
  ASSERT_EQ(run_cli({"bench", "--models", "2/16", "--size", "64", "--tiles", "32", "--backends", "eigen",
                     "--precisions", "fp32", "--repeat", "1", "--json"}, &out), 0) << out;
  const auto j = nlohmann::json::parse(out);
  const std::string cpu = j["cpu"];
  EXPECT_FALSE(cpu.empty());
  std::ifstream info("/proc/cpuinfo");
  const std::string text{std::istreambuf_iterator<char>(info), std::istreambuf_iterator<char>()};
  if (text.find("cpu family") != std::string::npos && text.find("model name") != std::string::npos) {
    EXPECT_NE(cpu.find("(family "), std::string::npos) << cpu;
  }
  ASSERT_EQ(j["rows"].size(), 1u) << out;
  const auto& row = j["rows"][0];
  const double warm = row["seconds_per_megapixel"], cold = row["first_run_seconds_per_megapixel"];
  EXPECT_TRUE(std::isfinite(warm) && warm > 0) << out;
  EXPECT_TRUE(std::isfinite(cold) && cold > 0) << out;
  // 2/16: head 9->16, four block convs and the tail 16->16, output 16->3; 2 x 9 taps x multiply-adds per pixel.
  EXPECT_NEAR(row["gflops"].get<double>() * warm, 2 * 9.0 * (9 * 16 + 5 * 16 * 16 + 16 * 3) / 1e3, 1e-6)
      << "GFLOP/s counts the useful work of the timed (warm) run";
}

// bench measures int8 for a model without a calibration (issue 55: "bench reports int8"), with ranges it measures
// on its own image; rated against four times the fp32 ceiling (VNNI's four multiply-adds a lane).
TEST(Cli, BenchMeasuresInt8WithoutACalibration) {
  if (!nn::bf16_available()) GTEST_SKIP() << "int8 is measured where oneDNN has AVX-512";
  std::string out;
  ASSERT_EQ(run_cli({"bench", "--models", "2/16", "--size", "64", "--tiles", "32", "--backends", "onednn",
                     "--precisions", "fp32,int8", "--repeat", "1", "--json"}, &out), 0) << out;
  const auto j = nlohmann::json::parse(out);
  ASSERT_EQ(j["rows"].size(), 2u) << out;
  const auto& fp32 = j["rows"][0];
  const auto& int8 = j["rows"][1];
  EXPECT_EQ(int8["precision"], "int8");
  EXPECT_NE(int8["implementation"].get<std::string>().find("onednn int8"), std::string::npos) << out;
  EXPECT_GT(int8["seconds_per_megapixel"].get<double>(), 0) << out;
  EXPECT_NEAR(int8["peak_gflops"].get<double>(), 4 * fp32["peak_gflops"].get<double>(), 1e-6);
}

TEST(Cli, InfoShowsTheMapping) {
  const auto dir = testing::shared_dataset("cycles-starter/s101");
  RESIDUE_REQUIRE_SHARED(dir);
  std::string out;
  ASSERT_EQ(run_cli({"info", (dir / "noisy_a.exr").string()}, &out), 0) << out;
  EXPECT_NE(out.find("Blender Cycles"), std::string::npos) << out;
  EXPECT_NE(out.find("ViewLayer.Denoising Normal"), std::string::npos) << out;
  ASSERT_EQ(run_cli({"info", "--json", (dir / "noisy_a.exr").string()}, &out), 0) << out;
  const auto j = nlohmann::json::parse(out);
  EXPECT_EQ(j["aovs"]["depth"]["channels"][0], "ViewLayer.Denoising Depth.Z");
  EXPECT_TRUE(j["aovs"]["variance"].is_null());
  EXPECT_EQ(j["normal_space"], "camera");
}

TEST(Cli, BundledExampleEvaluates) {
  const std::filesystem::path ex = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";
  const auto j = eval_json({(ex / "noisy.exr").string(), "--reference", (ex / "reference.exr").string()});
  const double relmse = j["rows"][0]["relmse"].get<double>();
  EXPECT_GT(relmse, 1e-3) << "an 8-spp render is visibly noisy";
  EXPECT_LT(relmse, 1.0);
  EXPECT_EQ(j["width"], 192);
}

TEST(Cli, MapsAndMetricsFilesAreWrittenAndNeverOverwritten) {
  const std::filesystem::path ex = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";
  TempDir tmp;
  const std::vector<std::string> args = {"eval", (ex / "noisy.exr").string(), "--reference",
                                         (ex / "reference.exr").string(), "--maps-dir", tmp.path().string(),
                                         "--map-format", "both", "--metrics-out", (tmp / "m.json").string()};
  std::string out;
  ASSERT_EQ(run_cli(args, &out), 0) << out;
  for (const char* kind : {"abs", "se", "rse", "ssim", "diff"}) {
    EXPECT_TRUE(std::filesystem::exists(tmp / (std::string("noisy_") + kind + ".png"))) << kind;
    EXPECT_TRUE(std::filesystem::exists(tmp / (std::string("noisy_") + kind + ".exr"))) << kind;
  }
  // The signed difference, against a float64 mean of x - r over RGB read here with OpenImageIO; its PNG is drawn
  // symmetric about 0 in the diverging map: a pixel equal to the reference would be white, the most negative one
  // the map's dark blue end.
  {
    OIIO::ImageBuf diff((tmp / "noisy_diff.exr").string()), noisy((ex / "noisy.exr").string()),
        ref((ex / "reference.exr").string());
    ASSERT_TRUE(diff.read(0, 0, true, OIIO::TypeDesc::FLOAT) && noisy.read(0, 0, true, OIIO::TypeDesc::FLOAT) &&
                ref.read(0, 0, true, OIIO::TypeDesc::FLOAT));
    const int nc = noisy.spec().nchannels, rc = ref.spec().nchannels;
    double worst = 0, lowest = 0;
    for (int y = 0; y < diff.spec().height; ++y)
      for (int x = 0; x < diff.spec().width; ++x) {
        std::vector<float> a(static_cast<size_t>(nc)), b(static_cast<size_t>(rc));
        float d = 0;
        noisy.getpixel(x, y, a.data(), nc);
        ref.getpixel(x, y, b.data(), rc);
        diff.getpixel(x, y, &d, 1);
        const double want = ((double(a[0]) - b[0]) + (double(a[1]) - b[1]) + (double(a[2]) - b[2])) / 3.0;
        worst = std::max(worst, std::abs(double(d) - want));
        lowest = std::min(lowest, want);
      }
    EXPECT_LT(worst, 1e-6);
    EXPECT_LT(lowest, 0.0) << "an 8-spp render has pixels darker than its reference";
  }
  // The mean of the relative squared error map is the relMSE in the metrics file.
  const auto metrics = nlohmann::json::parse(read_file(tmp / "m.json"));
  OIIO::ImageBuf rse((tmp / "noisy_rse.exr").string());
  const auto stats = OIIO::ImageBufAlgo::computePixelStats(rse);
  ASSERT_EQ(stats.avg.size(), 1u);
  EXPECT_NEAR(stats.avg[0], metrics["rows"][0]["relmse"].get<double>(), 1e-6);

  // Running again must not replace anything: exit code 4, files unchanged.
  const std::string before = read_file(tmp / "m.json");
  EXPECT_EQ(run_cli(args, &out), 4) << out;
  EXPECT_NE(out.find("--force"), std::string::npos) << out;
  EXPECT_EQ(read_file(tmp / "m.json"), before);
  std::vector<std::string> forced = args;
  forced.push_back("--force");
  EXPECT_EQ(run_cli(forced, &out), 0) << out;
}

TEST(Cli, CsvMetrics) {
  const std::filesystem::path ex = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";
  TempDir tmp;
  std::string out;
  ASSERT_EQ(run_cli({"eval", (ex / "noisy.exr").string(), "-r", (ex / "reference.exr").string(), "--roi",
                     "10,20,50,40", "--metrics-out", (tmp / "m.csv").string()},
                    &out),
            0)
      << out;
  const std::string csv = read_file(tmp / "m.csv");
  EXPECT_EQ(csv.rfind("name,test_file,mse,relmse,psnr,ssim,pixels", 0), 0u) << csv;
  EXPECT_NE(csv.find(",2000,"), std::string::npos) << "50x40 ROI pixels: " << csv;
}

TEST(Cli, ExitCodesForBadInput) {
  std::string out;
  // A missing reference is bad input like a missing render (exit 3, as the README says), named.
  const std::string room = std::string(RESIDUE_SOURCE_RESOURCES) + "/examples/room/noisy.exr";
  EXPECT_EQ(run_cli({"eval", room, "-r", "/no/such/ref.exr"}, &out), 3) << out;
  EXPECT_NE(out.find("/no/such/ref.exr"), std::string::npos) << out;
  EXPECT_EQ(run_cli({"info", "/no/such/file.exr"}, &out), 3) << out;
  EXPECT_NE(out.find("/no/such/file.exr"), std::string::npos) << out;
  EXPECT_EQ(run_cli({"frobnicate"}, &out), 2) << out;
  EXPECT_EQ(run_cli({}, &out), 2) << out;
  EXPECT_EQ(run_cli({"--help"}, &out), 0) << out;
  EXPECT_NE(out.find("eval"), std::string::npos) << out;
  EXPECT_EQ(run_cli({"eval", "--help"}, &out), 0) << out;
  EXPECT_NE(out.find("--denoised"), std::string::npos) << out;

  const std::filesystem::path ex = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";
  // Without -r, the reference beside the render (the data sets' layout) is used, and said; with none there, eval
  // asks for one.
  EXPECT_EQ(run_cli({"eval", (ex / "noisy.exr").string()}, &out), 0) << out;
  EXPECT_NE(out.find("'reference.exr' beside the render"), std::string::npos) << out;
  testing::TempDir alone;
  std::filesystem::copy_file(ex / "noisy.exr", alone / "noisy.exr");
  EXPECT_EQ(run_cli({"eval", (alone / "noisy.exr").string()}, &out), 2) << "no reference: " << out;
  EXPECT_NE(out.find("--reference"), std::string::npos) << out;
  EXPECT_EQ(run_cli({"eval", (ex / "noisy.exr").string(), "-r", (ex / "reference.exr").string(), "--roi", "0,0,5"},
                    &out),
            2)
      << out;
  EXPECT_EQ(run_cli({"eval", (ex / "noisy.exr").string(), "-r", (ex / "reference.exr").string(), "--roi",
                     "180,180,50,50"},
                    &out),
            2)
      << "ROI outside the image: " << out;
  TempDir tmp;
  testing::write_fixture_exr((tmp / "small.exr").string(),
                             {{"", {testing::constant_channel("R", 1), testing::constant_channel("G", 1),
                                    testing::constant_channel("B", 1)}, 0, 0, 8, 8}});
  EXPECT_EQ(run_cli({"eval", (ex / "noisy.exr").string(), "-r", (tmp / "small.exr").string()}, &out), 3) << out;
  EXPECT_NE(out.find("small.exr"), std::string::npos) << out;
}

}  // namespace
}  // namespace residue

namespace residue {
namespace {

// evaluate-set on two real starter scenes (linked into a temporary data set with its own index.json).
TEST(CliEvaluateSet, TableJsonSplitAndPerturbations) {
  const auto starter = testing::shared_dataset("cycles-starter");
  RESIDUE_REQUIRE_SHARED(starter);
  TempDir tmp;
  const auto data = tmp / "data";
  std::filesystem::create_directories(data);
  for (const char* s : {"s160", "s161"}) std::filesystem::create_directory_symlink(starter / s, data / s);
  std::ofstream(data / "index.json") << R"({"scenes": [{"folder": "s160", "split": "train"},
                                                      {"folder": "s161", "split": "validation"}]})";
  std::string text;
  ASSERT_EQ(run_cli({"evaluate-set", data.string(), "--models", "bilateral,tiny", "--json", (tmp / "a.json").string(),
                     "--md", (tmp / "a.md").string()},
                    &text),
            0)
      << text;
  std::ifstream in(tmp / "a.json");
  const auto j = nlohmann::json::parse(in);
  ASSERT_EQ(j["scenes"].size(), 2u);
  // The noisy column is the data set's own number (scene.json, computed by the generator in float64).
  std::ifstream sj(starter / "s160" / "scene.json");
  const auto scene = nlohmann::json::parse(sj);
  const double noisy = j["scenes"][0]["results"]["noisy"]["relmse"].get<double>();
  EXPECT_NEAR(noisy, scene["metrics"]["relmse_noisy_a"].get<double>(), 1e-9 * noisy);
  for (const auto& s : j["scenes"]) {
    EXPECT_LT(s["results"]["tiny"]["relmse"].get<double>(), s["results"]["noisy"]["relmse"].get<double>());
    EXPECT_NEAR(s["results"]["tiny"]["mean_ratio"].get<double>(), 1.0, 0.05);
    // HDR-FLIP beside them: the denoised image's is lower, and the noisy one's is eval's.
    EXPECT_LT(s["results"]["tiny"]["hdr_flip"].get<double>(), s["results"]["noisy"]["hdr_flip"].get<double>());
  }
  const auto eval = nlohmann::json::parse([&] {
    std::string out;
    EXPECT_EQ(run_cli({"eval", "--json", (starter / "s160" / "noisy_a.exr").string(), "-r",
                       (starter / "s160" / "reference.exr").string()}, &out), 0);
    return out;
  }());
  EXPECT_NEAR(j["scenes"][0]["results"]["noisy"]["hdr_flip"].get<double>(), eval["rows"][0]["hdr_flip"].get<double>(), 1e-12);
  EXPECT_GT(j["summary"][0]["mean_hdr_flip"].get<double>(), 0);
  EXPECT_NE(text.find("Mean brightness ratio"), std::string::npos);

  // --split validation: the index's cut.
  ASSERT_EQ(run_cli({"evaluate-set", data.string(), "--models", "tiny", "--split", "validation", "--json",
                     (tmp / "v.json").string()},
                    &text),
            0)
      << text;
  std::ifstream vin(tmp / "v.json");
  const auto v = nlohmann::json::parse(vin);
  ASSERT_EQ(v["scenes"].size(), 1u);
  EXPECT_EQ(v["scenes"][0]["scene"], "s161");
  const double tiny_s161 = v["scenes"][0]["results"]["tiny"]["relmse"].get<double>();

  // Depth units do not matter (depth is divided by its median), rotated normals do change the input.
  ASSERT_EQ(run_cli({"evaluate-set", data.string(), "--models", "tiny", "--split", "validation", "--perturb",
                     "depth-x100", "--json", (tmp / "d.json").string()},
                    &text),
            0)
      << text;
  std::ifstream din(tmp / "d.json");
  EXPECT_NEAR(nlohmann::json::parse(din)["scenes"][0]["results"]["tiny"]["relmse"].get<double>(), tiny_s161,
              0.02 * tiny_s161);
  ASSERT_EQ(run_cli({"evaluate-set", data.string(), "--models", "tiny", "--split", "validation", "--perturb",
                     "normals-world", "--json", (tmp / "n.json").string()},
                    &text),
            0)
      << text;
  std::ifstream nin(tmp / "n.json");
  EXPECT_NE(nlohmann::json::parse(nin)["scenes"][0]["results"]["tiny"]["relmse"].get<double>(), tiny_s161);

  EXPECT_EQ(run_cli({"evaluate-set", data.string(), "--models", "tiny", "--perturb", "sideways"}, &text), 2) << text;
  std::filesystem::remove(data / "index.json");
  EXPECT_EQ(run_cli({"evaluate-set", data.string(), "--models", "tiny", "--split", "validation"}, &text), 2) << text;
}

}  // namespace
}  // namespace residue
