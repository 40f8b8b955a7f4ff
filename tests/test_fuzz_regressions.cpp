// The fuzzers' seed corpora and the inputs that crashed them, replayed through the harnesses' own code
// (tests/fuzz/fuzz_targets.h) in the ordinary test suite. Under the asan preset this checks every seed and
// every former crash for memory errors, leaks and undefined behaviour; in any build it checks that bad bytes
// give a residue::Error, never a crash. The crash-* seeds of tests/fuzz/corpus are the fuzzers' findings.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/util/error.h"
#include "tests/fuzz/fuzz_targets.h"

namespace {

namespace fs = std::filesystem;

fs::path corpus_dir(const std::string& harness) {
  return fs::path(RESIDUE_TEST_FIXTURES).parent_path() / "fuzz" / "corpus" / harness;
}

std::vector<uint8_t> read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Every file of the harness's corpus through `one`; returns how many there were.
template <typename F>
int replay(const std::string& harness, F one) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(corpus_dir(harness))) {
    SCOPED_TRACE(e.path().string());
    const auto bytes = read_bytes(e.path());
    one(bytes.data(), bytes.size());
    ++n;
  }
  return n;
}

}  // namespace

TEST(FuzzCorpus, ExrLoaderSeedsAndCrashes) {
  EXPECT_GE(replay("fuzz_exr_loader", residue::fuzz::exr_loader_one), 10);
}

TEST(FuzzCorpus, SafetensorsSeedsAndCrashes) {
  EXPECT_GE(replay("fuzz_safetensors", residue::fuzz::safetensors_one), 5);
}

TEST(FuzzCorpus, TzaSeedsAndCrashes) { EXPECT_GE(replay("fuzz_tza", residue::fuzz::tza_one), 5); }

TEST(FuzzCorpus, ChannelMappingSeedsAndCrashes) {
  EXPECT_GE(replay("fuzz_channel_mapping", residue::fuzz::channel_mapping_one), 6);
}

TEST(FuzzCorpus, TevIpcSeedsAndCrashes) { EXPECT_GE(replay("fuzz_tev_ipc", residue::fuzz::tev_ipc_one), 10); }

TEST(FuzzCorpus, LiveImagesSeedsAndCrashes) {
  EXPECT_GE(replay("fuzz_live_images", residue::fuzz::live_images_one), 10);
}

// The seeds are real: each model seed loads, so the fuzzers start from inputs that reach the deep code.
TEST(FuzzCorpus, ModelSeedsAreValid) {
  int seeds = 0;
  for (const auto& e : fs::directory_iterator(corpus_dir("fuzz_safetensors"))) {
    if (e.path().filename().string().rfind("crash-", 0) == 0) continue;
    SCOPED_TRACE(e.path().string());
    EXPECT_NO_THROW((void)residue::nn::load_model(e.path()));
    ++seeds;
  }
  EXPECT_GE(seeds, 3) << "an empty or missing corpus checks nothing";
  for (const std::string name : {"rt_hdr_alb_nrm_div16.tza", "rt_hdr_div16_f32.tza", "rt_hdr_calb_cnrm_large_div32.tza"}) {
    SCOPED_TRACE(name);
    const auto file = residue::nn::read_tza(corpus_dir("fuzz_tza") / name);
    const int channels = name.rfind("rt_hdr_div16", 0) == 0 ? 3 : 9;
    EXPECT_NO_THROW((void)residue::nn::oidn_graph(file, channels, name));
  }
}

// Found by review while writing the fuzz harnesses (not by a fuzzer run; the fuzzers' inputs are too short to
// reach it): tensors whose data overlap. Every tensor lay inside the file, so each check passed, and a small file
// could make the reader allocate count x its size in floats (a 1 MB .tza: 200 GB). Now the tensors together may
// not claim more bytes than the file holds.
TEST(FuzzRegressions, TzaTensorsSharingTheirDataAreRefused) {
  // Header (magic 0x41D7, version 2.0, table at 76), 64 bytes of data, then 3 uint8 tensors "a", "b", "c" of
  // shape [64], layout "x", every one at offset 12.
  std::vector<uint8_t> bytes(76, 7);
  // push_back, not insert: gcc 12 -O3 sees a false out-of-bounds memmove in vector::insert here (-Warray-bounds).
  auto append = [&](std::initializer_list<uint8_t> values) {
    for (uint8_t v : values) bytes.push_back(v);
  };
  const uint8_t header[] = {0xD7, 0x41, 2, 0, 76, 0, 0, 0, 0, 0, 0, 0};
  std::copy(std::begin(header), std::end(header), bytes.begin());
  append({3, 0, 0, 0});
  for (char name : {'a', 'b', 'c'})
    append({1, 0, static_cast<uint8_t>(name), 1, 64, 0, 0, 0, 'x', 'B', 12, 0, 0, 0, 0, 0, 0, 0});
  try {
    (void)residue::nn::parse_tza(bytes, "aliased.tza");
    FAIL() << "expected residue::Error";
  } catch (const residue::Error& e) {
    EXPECT_EQ(e.kind(), residue::ErrorKind::Input);
    EXPECT_NE(std::string(e.what()).find("tensor \"c\" brings the tensors' data to more than the file's"),
              std::string::npos) << e.what();
  }
  residue::fuzz::tza_one(bytes.data(), bytes.size());
  // Two tensors of 32 bytes sharing their data fit in the (116-byte) file: still read, as before (the check bounds
  // the total, it does not demand a layout).
  bytes[76] = 2;
  bytes.resize(bytes.size() - 18);
  bytes[80 + 4] = bytes[80 + 18 + 4] = 32;
  EXPECT_EQ(residue::nn::parse_tza(bytes, "two.tza").tensors.size(), 2u);
}

TEST(FuzzRegressions, SafetensorsTensorsSharingTheirDataAreRefused) {
  const std::string header = R"({"a":{"dtype":"F32","shape":[4],"data_offsets":[0,16]},)"
                             R"("b":{"dtype":"F32","shape":[4],"data_offsets":[0,16]}})";
  std::vector<uint8_t> bytes(8, 0);
  bytes[0] = static_cast<uint8_t>(header.size());
  bytes.insert(bytes.end(), header.begin(), header.end());
  bytes.resize(bytes.size() + 16, 0);
  const auto path = residue::fuzz::write_input("aliased.safetensors", bytes.data(), bytes.size());
  try {
    (void)residue::nn::read_safetensors(path);
    FAIL() << "expected residue::Error";
  } catch (const residue::Error& e) {
    EXPECT_EQ(e.kind(), residue::ErrorKind::Input);
    EXPECT_NE(std::string(e.what()).find("tensor \"b\" brings the tensors' data to more than the 16 bytes"),
              std::string::npos) << e.what();
  }
  residue::fuzz::safetensors_one(bytes.data(), bytes.size());
}

// OpenEXR 3.1 allocates the size a header declares for an attribute before reading it (1.9 GB for a 2.6 KB file):
// the loader refuses such headers first, naming the file and what the header declares.
TEST(FuzzRegressions, ExrHeaderDeclaringMoreThanTheFileIsRefusedBeforeOpening) {
  for (const char* name : {"crash-oom-openexr-string-attribute-1.exr", "crash-oom-openexr-string-attribute-2.exr"}) {
    const fs::path path = corpus_dir("fuzz_exr_loader") / name;
    try {
      (void)residue::load_aov_stack({path}, residue::LoadOptions{});
      FAIL() << "expected residue::Error for " << name;
    } catch (const residue::Error& e) {
      EXPECT_EQ(e.kind(), residue::ErrorKind::Input);
      const std::string what = e.what();
      EXPECT_NE(what.find(name), std::string::npos) << what;
      EXPECT_NE(what.find("header declares a string attribute of"), std::string::npos) << what;
    }
  }
  // A real render passes; the same render with the size of its channel list made larger than the file does not,
  // and the message names the attribute.
  const fs::path room = fs::path(RESIDUE_SOURCE_RESOURCES) / "examples" / "room" / "noisy.exr";
  auto bytes = read_bytes(room);
  ASSERT_GT(bytes.size(), 64u);
  EXPECT_FALSE(residue::exr_header_problem(bytes.data(), bytes.size(), bytes.size()));
  const std::string channels("channels\0chlist", 15);
  const auto at = std::search(bytes.begin(), bytes.end(), channels.begin(), channels.end());
  ASSERT_NE(at, bytes.end());
  const size_t size_at = static_cast<size_t>(at - bytes.begin()) + channels.size() + 1;
  for (size_t i = 0; i < 4; ++i) bytes[size_at + i] = 0x7f;
  const auto problem = residue::exr_header_problem(bytes.data(), bytes.size(), bytes.size());
  ASSERT_TRUE(problem);
  EXPECT_NE(problem->find("the attribute 'channels'"), std::string::npos) << *problem;
  const auto path = residue::fuzz::write_input("huge_attribute.exr", bytes.data(), bytes.size());
  EXPECT_THROW((void)residue::list_channels(path), residue::Error);
}

// A 3 KB file whose data window is 33554438 x 6 pixels of 16 float channels: opening it, OpenEXR 3.1 allocates a
// 2.6 GB line buffer, which libFuzzer reports as out of memory (found by fuzz_exr_loader in CI), and `residue-cli
// info` used 8 GB and ended in bad_alloc. The loader refuses a window no codec could pack into the file, naming it
// (48 bytes a pixel: the 12 float channels its channel list's declared size holds); every real seed passes.
TEST(FuzzRegressions, ExrWindowLargerThanTheFileCanHoldIsRefusedBeforeOpening) {
  const fs::path path = corpus_dir("fuzz_exr_loader") / "crash-oom-openexr-data-window-line-buffer.exr";
  try {
    (void)residue::load_aov_stack({path}, residue::LoadOptions{});
    FAIL() << "expected residue::Error";
  } catch (const residue::Error& e) {
    EXPECT_EQ(e.kind(), residue::ErrorKind::Input);
    const std::string what = e.what();
    EXPECT_NE(what.find(path.filename().string()), std::string::npos) << what;
    EXPECT_NE(what.find("a window of 33554438 x 6 pixels of 48 bytes, more than a file of 3108 bytes can hold"),
              std::string::npos) << what;
  }
  int seeds = 0;
  for (const auto& e : fs::directory_iterator(corpus_dir("fuzz_exr_loader"))) {
    const std::string name = e.path().filename().string();
    if (name.rfind("crash-", 0) == 0 || name.rfind("slow-", 0) == 0) continue;  // the fuzzers' findings
    const auto bytes = read_bytes(e.path());
    EXPECT_FALSE(residue::exr_header_problem(bytes.data(), bytes.size(), bytes.size())) << e.path();
    ++seeds;
  }
  EXPECT_GE(seeds, 5) << "an empty or missing corpus checks nothing";
  // The bundled render with its data window's xMax raised: 256 MiB of pixels pass whatever the file's size, more
  // than 65536x the file's bytes does not.
  auto room = read_bytes(fs::path(RESIDUE_SOURCE_RESOURCES) / "examples" / "room" / "noisy.exr");
  const std::string window("dataWindow\0box2i", 16);
  const auto at = std::search(room.begin(), room.end(), window.begin(), window.end());
  ASSERT_NE(at, room.end());
  const size_t x_max = static_cast<size_t>(at - room.begin()) + window.size() + 1 + 4 + 8;
  auto set_x_max = [&](uint32_t v) {
    for (size_t i = 0; i < 4; ++i) room[x_max + i] = static_cast<uint8_t>(v >> (8 * i));
  };
  const auto problem_at = [&](uint64_t file_size) { return residue::exr_header_problem(room.data(), room.size(), file_size); };
  set_x_max(1000);  // 1001 columns x 256 lines (a chunk) x its bytes per pixel: far below 256 MiB
  EXPECT_FALSE(problem_at(room.size()));
  set_x_max(20000000);
  EXPECT_TRUE(problem_at(room.size()));
  EXPECT_FALSE(problem_at(uint64_t{1} << 40)) << "a file large enough for it";
}

// The harness's own size gate (1 Mi values) reads the bytes too, never OpenImageIO's open, which allocates: the
// count it skips by must be the header's, checked against OpenImageIO's spec.
TEST(FuzzRegressions, ExrDeclaringAHugeWindowIsSkippedBeforeOpening) {
  const auto found = read_bytes(corpus_dir("fuzz_exr_loader") / "crash-oom-openexr-data-window-line-buffer.exr");
  ASSERT_GT(found.size(), 1000u);
  const double declared = residue::fuzz::exr_declared_values(found.data(), found.size());
  EXPECT_GT(declared, static_cast<double>(residue::fuzz::kMaxExrValues));
  EXPECT_EQ(std::fmod(declared, 33554438.0 * 6), 0.0) << declared;  // the data window, times whole channels
  // Real renders: exactly the larger window's pixels times the channels, as OpenImageIO reads the headers.
  for (const fs::path& real : {fs::path(RESIDUE_SOURCE_RESOURCES) / "examples" / "room" / "noisy.exr",
                               corpus_dir("fuzz_exr_loader") / "plain_layers_offset_window.exr",
                               corpus_dir("fuzz_exr_loader") / "arnold_negative_origin.exr"}) {
    SCOPED_TRACE(real.string());
    auto in = OIIO::ImageInput::open(real.string());
    ASSERT_TRUE(in);
    const OIIO::ImageSpec& spec = in->spec();
    const double pixels = std::max(double(spec.width) * spec.height, double(spec.full_width) * spec.full_height);
    const auto bytes = read_bytes(real);
    EXPECT_EQ(residue::fuzz::exr_declared_values(bytes.data(), bytes.size()), pixels * spec.nchannels);
  }
}

// OpenImageIO 2.4 aborts the process (an assertion) on a channel whose pixel type is not 0, 1 or 2: found by a
// one-hour run of fuzz_exr_loader. The loader refuses it first, naming the channel; the fuzzer's input is a seed.
TEST(FuzzRegressions, ExrChannelWithAnUnknownPixelTypeIsRefusedNotAnAbort) {
  const fs::path found = corpus_dir("fuzz_exr_loader") / "crash-oiio-abort-pixel-type-3.exr";
  try {
    (void)residue::list_channels(found);
    FAIL() << "expected residue::Error";
  } catch (const residue::Error& e) {
    // Its channel list is wrong twice over (a sampling of -1 first, then the pixel type 3 OpenImageIO aborted on).
    EXPECT_NE(std::string(e.what()).find("the channel 'G' has sampling 1x-1"), std::string::npos) << e.what();
  }
  // The bundled render with its first channel's pixel type set to 3, then its sampling to 0.
  auto bytes = read_bytes(fs::path(RESIDUE_SOURCE_RESOURCES) / "examples" / "room" / "noisy.exr");
  const std::string chlist("chlist", 7);
  const auto at = std::search(bytes.begin(), bytes.end(), chlist.begin(), chlist.end());
  ASSERT_NE(at, bytes.end());
  const size_t list = static_cast<size_t>(at - bytes.begin()) + chlist.size() + 4;
  const auto name_end = std::find(bytes.begin() + static_cast<std::ptrdiff_t>(list), bytes.end(), uint8_t{0});
  const std::string first(bytes.begin() + static_cast<std::ptrdiff_t>(list), name_end);
  const size_t type_at = static_cast<size_t>(name_end - bytes.begin()) + 1;
  auto type3 = bytes;
  type3[type_at] = 3;
  auto problem = residue::exr_header_problem(type3.data(), type3.size(), type3.size());
  ASSERT_TRUE(problem);
  EXPECT_NE(problem->find("the channel '" + first + "' has pixel type 3"), std::string::npos) << *problem;
  auto sampling0 = bytes;
  sampling0[type_at + 8] = 0;
  problem = residue::exr_header_problem(sampling0.data(), sampling0.size(), sampling0.size());
  ASSERT_TRUE(problem);
  EXPECT_NE(problem->find("has sampling 0x1"), std::string::npos) << *problem;
}

// fuzz_safetensors: a shape or data offset written as a huge float (4.3e81) was converted to an integer out of
// range (undefined behaviour, UBSan); now refused, naming the tensor and the field.
TEST(FuzzRegressions, SafetensorsNonIntegerShapesAreRefused) {
  for (const char* shape : {"[4.3e81]", "[2.5]", "[\"4\"]"}) {
    const std::string header = std::string(R"({"a":{"dtype":"F32","shape":)") + shape + R"(,"data_offsets":[0,16]}})";
    std::vector<uint8_t> bytes(8, 0);
    bytes[0] = static_cast<uint8_t>(header.size());
    bytes.insert(bytes.end(), header.begin(), header.end());
    bytes.resize(bytes.size() + 16, 0);
    const auto path = residue::fuzz::write_input("float_shape.safetensors", bytes.data(), bytes.size());
    try {
      (void)residue::nn::read_safetensors(path);
      FAIL() << "expected residue::Error for shape " << shape;
    } catch (const residue::Error& e) {
      EXPECT_NE(std::string(e.what()).find("tensor \"a\": shape holds"), std::string::npos) << e.what();
    }
  }
}
