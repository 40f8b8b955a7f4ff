// The second bad-input audit (issue 49): each test is one defect found there, end to end where the user meets
// it, on the bundled room example. Suites that start residue-cli have "Cli" in their name (the sanitizer run in
// .ci/run leaves those out).
#include <sys/mount.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <limits>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoiser.h"
#include "core/io/atomic_file.h"
#include "core/io/frame_claim.h"
#include "core/ipc/live_images.h"
#include "core/nn/model_file.h"
#include "core/nn/model_registry.h"
#include "support/exr_fixture.h"
#include "support/test_support.h"

namespace residue {
namespace {

namespace fs = std::filesystem;
using testing::run_cli;
using testing::TempDir;
using testing::read_text;

const fs::path kRoom = fs::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// A two-frame shot (the room twice) and a mapping file, in a fresh folder.
class TrustSequenceCli : public ::testing::Test {
 protected:
  void SetUp() override {
    for (const char* f : {"shot.0001.exr", "shot.0002.exr"}) fs::copy_file(kRoom / "noisy.exr", dir_ / f);
    frame1_ = read_text(dir_ / "shot.0001.exr");
  }
  std::vector<std::string> sequence(const std::vector<std::string>& extra) const {
    std::vector<std::string> args = {"denoise", (dir_ / "shot.####.exr").string(), "-o", (dir_ / "out.####.exr").string(),
                                     "-m", "tiny"};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  }
  TempDir dir_;
  std::string frame1_;
};

// Defect 2: `--summary shot.0001.exr --force` turned frame 1 into JSON.
TEST_F(TrustSequenceCli, SummaryNamedLikeAFrameIsRefused) {
  std::string out;
  EXPECT_EQ(run_cli(sequence({"--summary", (dir_ / "shot.0001.exr").string(), "--force"}), &out), 2) << out;
  EXPECT_TRUE(contains(out, "--summary") && contains(out, "ending in .json")) << out;
  EXPECT_EQ(read_text(dir_ / "shot.0001.exr"), frame1_);
  EXPECT_FALSE(fs::exists(dir_ / "out.0001.exr")) << "refused before any frame ran";
}

// Defect 2: a summary may not replace any file the run reads, whatever its name (here the mapping file).
TEST_F(TrustSequenceCli, SummaryOverAnInputIsRefusedEvenWithForce) {
  const fs::path mapping = dir_ / "mapping.json";
  std::ofstream(mapping) << R"({"color": {"channels": ["R", "G", "B"]}})";
  const std::string before = read_text(mapping);
  std::string out;
  EXPECT_EQ(run_cli(sequence({"--mapping", mapping.string(), "--summary", mapping.string(), "--force"}), &out), 4) << out;
  EXPECT_TRUE(contains(out, "is the input")) << out;
  EXPECT_EQ(read_text(mapping), before);
}

// Defects 2 and 9: evaluate-set's --json over a scene's scene.json is refused, before any model runs; so is a
// Markdown table not named .md.
TEST(TrustEvaluateSetCli, OutputsAreCheckedFirstAndNeverReplaceTheDataSet) {
  TempDir dir;
  fs::create_directories(dir / "s0001");
  fs::copy_file(kRoom / "noisy.exr", dir / "s0001/noisy_a.exr");
  fs::copy_file(kRoom / "reference.exr", dir / "s0001/reference.exr");
  std::ofstream(dir / "s0001/scene.json") << "{\"scene_seed\": 1}";
  const std::string scene_json = read_text(dir / "s0001/scene.json");
  std::string out;
  EXPECT_EQ(run_cli({"evaluate-set", dir.path().string(), "--models", "tiny", "--json", (dir / "s0001/scene.json").string(),
                     "-f"}, &out), 4) << out;
  EXPECT_TRUE(contains(out, "is the input")) << out;
  EXPECT_EQ(read_text(dir / "s0001/scene.json"), scene_json);
  EXPECT_FALSE(contains(out, "evaluate-set: 1/1")) << "refused before the first scene: " << out;
  EXPECT_EQ(run_cli({"evaluate-set", dir.path().string(), "--models", "tiny", "--md", (dir / "table.exr").string()}, &out), 2)
      << out;
  EXPECT_TRUE(contains(out, "--md") && contains(out, "ending in .md")) << out;
  EXPECT_FALSE(contains(out, "evaluate-set: 1/1")) << out;
  EXPECT_EQ(run_cli({"evaluate-set", dir.path().string(), "--models", "tiny", "--md", (dir / "no/such/t.md").string()}, &out), 4)
      << out;
  EXPECT_FALSE(contains(out, "evaluate-set: 1/1")) << "a folder that does not exist is found before the run: " << out;
}

// Defect 6: `-o /dev/null --force` would have replaced the device with a regular file (as root).
TEST(TrustOutputs, DevicesAndFifosAreNeverReplaced) {
  EXPECT_TRUE(contains(testing::error_message([] { io::prepare_output("/dev/null", true); }, ErrorKind::Output),
                       "is a character device"));
  struct stat st {};
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
  TempDir dir;
  ASSERT_EQ(::mkfifo((dir / "pipe.exr").c_str(), 0644), 0);
  EXPECT_TRUE(contains(testing::error_message([&] { io::prepare_output(dir / "pipe.exr", true); }, ErrorKind::Output),
                       "is a FIFO"));
  fs::create_symlink("/dev/null", dir / "link.exr");
  EXPECT_TRUE(contains(testing::error_message([&] { io::prepare_output(dir / "link.exr", true); }, ErrorKind::Output),
                       "is a character device"));
}

TEST(TrustOutputsCli, DeviceOutputIsRefusedByDenoise) {
  std::string out;
  EXPECT_EQ(run_cli({"denoise", (kRoom / "noisy.exr").string(), "-m", "tiny", "-o", "/dev/null", "--force"}, &out), 4) << out;
  EXPECT_TRUE(contains(out, "'/dev/null' is a character device")) << out;
}

// Defect 20: a 244-byte output name (legal: NAME_MAX is 255) was refused because its temporary name was longer.
TEST(TrustOutputsCli, LongOutputNameIsWritten) {
  TempDir dir;
  const fs::path output = dir / (std::string(240, 'a') + ".exr");
  std::string out;
  EXPECT_EQ(run_cli({"denoise", (kRoom / "noisy.exr").string(), "-m", "tiny", "-o", output.string()}, &out), 0) << out;
  EXPECT_TRUE(fs::is_regular_file(output));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1) << "no temporary file left";
}

// Defect 19: a full disk was reported naming the hidden temporary file, never saying the disk was full. A small
// tmpfs stands for the full disk (mounting needs root: skipped otherwise).
TEST(TrustOutputsCli, FullDiskIsSaidAndNamesTheOutput) {
  TempDir dir;
  const fs::path mount_point = dir / "small";
  fs::create_directory(mount_point);
  if (::mount("tmpfs", mount_point.c_str(), "tmpfs", 0, "size=64k") != 0)
    GTEST_SKIP() << "cannot mount a small tmpfs here (needs root)";
  std::string out;
  const int code = run_cli({"denoise", (kRoom / "noisy.exr").string(), "-m", "tiny", "--float", "--compression", "none",
                            "-o", (mount_point / "out.exr").string()}, &out);
  const auto left = std::distance(fs::directory_iterator(mount_point), fs::directory_iterator());
  ::umount(mount_point.c_str());
  EXPECT_EQ(code, 4) << out;
  EXPECT_TRUE(contains(out, "no space left on device")) << out;
  EXPECT_TRUE(contains(out, "out.exr'")) << out;
  EXPECT_FALSE(contains(out, "residue-tmp")) << "the temporary file is not the user's business: " << out;
  EXPECT_EQ(left, 0) << "the temporary file is removed";
}

// Defect 4: devices, FIFOs and sockets spun or blocked for ever in info, denoise and the viewer; a link loop was
// an internal error (defect 13). Each is refused at once, named, exit 3.
TEST(TrustInputsCli, NonRegularFilesAreRefusedAtOnce) {
  TempDir dir;
  ASSERT_EQ(::mkfifo((dir / "pipe.exr").c_str(), 0644), 0);
  fs::create_symlink("/dev/zero", dir / "zero.exr");
  fs::create_symlink(dir / "b.exr", dir / "a.exr");
  fs::create_symlink(dir / "a.exr", dir / "b.exr");
  const std::pair<fs::path, std::string> cases[] = {
      {"/dev/zero", "is a device"},      {"/dev/urandom", "is a device"},
      {dir / "zero.exr", "is a device"}, {dir / "pipe.exr", "is a pipe (FIFO): pipes are not supported"},
      {dir / "a.exr", "is a loop of symbolic links"}};
  for (const auto& [path, says] : cases)
    for (const char* command : {"info", "denoise"}) {
      std::vector<std::string> args = {command, path.string()};
      if (std::string(command) == "denoise") args.insert(args.end(), {"-m", "tiny", "-o", (dir / "out.exr").string()});
      std::string out;
      EXPECT_EQ(run_cli(args, &out), 3) << command << " " << path << ": " << out;
      EXPECT_TRUE(contains(out, "'" + path.string() + "' " + says))
          << command << " " << path << ": " << out;
    }
  std::string out;
  EXPECT_EQ(run_cli({"denoise", (kRoom / "noisy.exr").string(), "-m", "/dev/null", "-o", (dir / "out.exr").string()}, &out), 3)
      << out;
  EXPECT_TRUE(contains(out, "model file '/dev/null' is a device")) << out;
  // /dev/stdin that is a regular file (a redirection) is a regular file: it keeps working.
  EXPECT_EQ(testing::run_program("/bin/sh", {"-c", std::string(RESIDUE_CLI_PATH) + " info /dev/stdin < " +
                                                       (kRoom / "noisy.exr").string()}, &out), 0) << out;
  EXPECT_TRUE(contains(out, "192 x 192")) << out;
}

// Defect 19: `--map depth=/missing/z.exr` reported the file as a missing channel.
TEST(TrustInputsCli, MissingMapFileIsNamedAsAFile) {
  TempDir dir;
  std::string out;
  EXPECT_EQ(run_cli({"info", (kRoom / "noisy.exr").string(), "--map", "depth=/missing/z.exr"}, &out), 3) << out;
  EXPECT_TRUE(contains(out, "the file '/missing/z.exr' does not exist")) << out;
}

// Defect 19: a deep EXR said "read_native_scanlines without an open file".
TEST(TrustInputsCli, DeepImagesAreRefusedByName) {
  TempDir dir;
  const fs::path deep = dir / "deep.exr";
  std::string out;
  ASSERT_EQ(testing::run_program("/usr/bin/oiiotool", {"--pattern", "constant:color=0.5,0.5,0.5,1", "8x8", "4", "--chnames", "R,G,B,Z", "--deepen", "-o",
                                              deep.string()}, &out), 0) << out;
  EXPECT_EQ(run_cli({"info", deep.string()}, &out), 3) << out;
  EXPECT_TRUE(contains(out, "is a deep image") && contains(out, "not supported")) << out;
}

// Defect 8: a valid region render (a 64x64 data window in a 16384x8640 display window, a few KB) was refused as
// corrupt: the header's size check counted the display window, which nothing reads.
TEST(TrustInputsCli, RegionRenderInAHugeDisplayWindowLoads) {
  TempDir dir;
  testing::FixturePart part;
  part.x = 8000, part.y = 4000, part.width = 64, part.height = 64;
  part.full_width = 16384, part.full_height = 8640;
  for (const char* c : {"R", "G", "B"}) part.channels.push_back({c, true, [](int x, int) { return 0.01f * static_cast<float>(x % 50); }});
  testing::write_fixture_exr((dir / "region.exr").string(), {part});
  ASSERT_LT(fs::file_size(dir / "region.exr"), 64u * 1024);
  std::string out;
  EXPECT_EQ(run_cli({"info", (dir / "region.exr").string()}, &out), 0) << out;
  EXPECT_TRUE(contains(out, "64 x 64")) << out;
  EXPECT_EQ(run_cli({"denoise", (dir / "region.exr").string(), "-o", (dir / "out.exr").string()}, &out), 0) << out;
}

// Defect 14: a uint channel (an ID pass) read as colour was scaled by 1/(2^32-1) without a word.
TEST(TrustInputs, IntegerChannelsAreRefusedByName) {
  TempDir dir;
  const fs::path file = dir / "ids.exr";
  OIIO::ImageSpec spec(8, 8, 3, OIIO::TypeUInt);
  spec.channelnames = {"R", "G", "B"};
  std::vector<uint32_t> pixels(8 * 8 * 3, 7);
  auto out = OIIO::ImageOutput::create(file.string());
  ASSERT_TRUE(out && out->open(file.string(), spec) && out->write_image(OIIO::TypeUInt, pixels.data()) && out->close());
  const std::string message = testing::error_message([&] { load_aov_stack({file}); }, ErrorKind::Input);
  EXPECT_TRUE(contains(message, "channel 'R' is an integer (uint) channel")) << message;
}

// Defect 14: --map albedo=FILE on a multilayer render took its first layer (the beauty), not its albedo layer.
TEST(TrustInputs, MappedMultilayerFileGivesItsOwnAov) {
  LoadOptions o;
  o.mapping.add_flag("albedo=" + (kRoom / "noisy.exr").string());
  const AovStack mapped = load_aov_stack({kRoom / "noisy.exr"}, o);
  const AovStack plain = load_aov_stack({kRoom / "noisy.exr"});
  ASSERT_TRUE(mapped.albedo && plain.albedo);
  EXPECT_EQ(mapped.albedo->source.layer, plain.albedo->source.layer);
  for (size_t i = 0; i < plain.albedo->image.size(); ++i)
    ASSERT_EQ(mapped.albedo->image.data()[i], plain.albedo->image.data()[i]) << i;
}

// Defect 14: an albedo that is all NaN was sanitised to 0 and used without a warning.
TEST(TrustInputs, AGuideWithNoFiniteValueIsSaid) {
  TempDir dir;
  testing::FixturePart part;
  part.width = part.height = 16;
  for (const char* c : {"R", "G", "B"}) part.channels.push_back(testing::constant_channel(c, 0.5f));
  for (const char* c : {"albedo.R", "albedo.G", "albedo.B"})
    part.channels.push_back(testing::constant_channel(c, std::numeric_limits<float>::quiet_NaN()));
  testing::write_fixture_exr((dir / "nan_albedo.exr").string(), {part});
  const AovStack s = load_aov_stack({dir / "nan_albedo.exr"});
  bool said = false;
  for (const auto& n : s.notes) said = said || contains(n, "albedo AOV has no finite value");
  EXPECT_TRUE(said);
}

// Defect 15: --layer Beta did not select a layer whose beauty is Beta.R/G/B (and its passes Beta.albedo.R, ...);
// an unknown --layer was reported as "no colour channels".
TEST(TrustInputs, LayerSelectsAPlainLayerAndAnUnknownOneIsNamed) {
  TempDir dir;
  testing::FixturePart part;
  part.width = part.height = 16;
  for (const char* c : {"R", "G", "B"}) part.channels.push_back(testing::constant_channel(c, 0.25f));
  for (const char* c : {"Beta.R", "Beta.G", "Beta.B"}) part.channels.push_back(testing::constant_channel(c, 0.75f));
  for (const char* c : {"Beta.albedo.R", "Beta.albedo.G", "Beta.albedo.B"})
    part.channels.push_back(testing::constant_channel(c, 0.5f));
  testing::write_fixture_exr((dir / "layers.exr").string(), {part});
  LoadOptions o;
  o.mapping.layer_prefix = "Beta";
  const AovStack beta = load_aov_stack({dir / "layers.exr"}, o);
  EXPECT_EQ(beta.color.image.at(3, 3, 0), 0.75f);
  ASSERT_TRUE(beta.albedo.has_value());
  EXPECT_EQ(beta.albedo->image.at(3, 3, 1), 0.5f);
  o.mapping.layer_prefix = "Gamma";
  const std::string message = testing::error_message([&] { load_aov_stack({dir / "layers.exr"}, o); }, ErrorKind::Input);
  EXPECT_TRUE(contains(message, "--layer 'Gamma'") && contains(message, "no such layer") && contains(message, "Beta"))
      << message;
}

// Defect 23: `residue-cli denoise render.exr -o out.exr` answered "--model is required" although the README
// names the default model.
TEST(TrustOptionsCli, TheDefaultModelNeedsNoFlag) {
  TempDir dir;
  std::string out;
  EXPECT_EQ(run_cli({"denoise", (kRoom / "noisy.exr").string(), "-o", (dir / "out.exr").string()}, &out), 0) << out;
  EXPECT_TRUE(contains(out, std::string("model      ") + nn::kDefaultModel)) << out;
  EXPECT_EQ(run_cli({"denoise", "--help"}, &out), 0);
  EXPECT_TRUE(contains(out, std::string("TEXT=") + nn::kDefaultModel)) << "--help names the default: " << out;
}

// Defects 16 and 21: options that ran as something else or measured nothing with exit 0 are refused, exit 2.
TEST(TrustOptionsCli, LenientOptionsAreRefused) {
  TempDir dir;
  const std::string room = (kRoom / "noisy.exr").string(), out_exr = (dir / "o.exr").string();
  const std::string shot = (dir / "shot.####.exr").string(), outs = (dir / "out.####.exr").string();
  fs::copy_file(kRoom / "noisy.exr", dir / "shot.0001.exr");
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"denoise", shot, "-o", outs, "--frames", ""}, "--frames"},
      {{"denoise", shot, "-o", outs, "--skip-existing", "--force"}, "excludes"},
      {{"denoise", room, "-o", out_exr, "-m", "bilateral", "--ensemble", "8"}, "bilateral filter has none"},
      {{"denoise", room, "-o", out_exr, "--compression", "zip:99"}, "1 to 9"},
      {{"denoise", room, "-o", out_exr, "--compression", "dwaa:-5"}, "positive whole number"},
      {{"denoise", room, "-o", out_exr, "--compression", "piz:3"}, "takes no level"},
      {{"evaluate-set", dir.path().string(), "--models", "tiny", "--last", "0"}, "--last"},
      {{"evaluate-set", dir.path().string(), "--models", "tiny", "--threads", "-3"}, "--threads"},
      {{"evaluate-set", dir.path().string(), "--models", "tiny", "--blend-tau", "nan"}, "finite number"},
      {{"eval", room, "--eps", "0"}, "finite number above 0"},
      {{"farm", "slurm", shot, "-o", outs, "-m", "tiny", "--max-parallel", "-1"}, "--max-parallel"},
      {{"farm", "slurm", shot, "-o", outs, "-m", "tiny", "--chunk", "0"}, "--chunk"},
      {{"bench", "--backends", "bogus"}, "--backends"},
      {{"bench", "--precisions", "fp64"}, "--precisions"},
      {{"bench", "--tiles", "-1"}, "--tiles"},
      {{"bench", "--cancel-after", "nan"}, "--cancel-after"},
      {{"bench", "--models", "100000/8"}, "at most 256 blocks"},
  };
  for (const auto& [args, says] : cases) {
    std::string out;
    EXPECT_EQ(run_cli(args, &out), 2) << args[0] << " " << says << ": " << out;
    EXPECT_TRUE(contains(out, says)) << says << ": " << out;
    EXPECT_LT(out.size(), 2000u) << "a short message (no 309-digit bound): " << out;
    EXPECT_FALSE(contains(out, "ceiling measured")) << "refused before measuring: " << out;
  }
  EXPECT_FALSE(fs::exists(dir / "out.0001.exr"));
  std::string out;
  EXPECT_EQ(run_cli({"denoise", room, "-o", (dir / ".exr").string()}, &out), 4) << out;
  EXPECT_TRUE(contains(out, "is an extension without a name")) << out;
}

// Defect 17: --skip-existing took a 0-byte or truncated output as done; defect 7: a frame claimed by another
// process (a requeued farm task beside the first) is that process's, not done twice nor failed.
TEST_F(TrustSequenceCli, SkipExistingRedoesDamagedFramesAndLeavesClaimedOnes) {
  fs::copy_file(kRoom / "noisy.exr", dir_ / "shot.0003.exr");
  std::string out;
  ASSERT_EQ(run_cli(sequence({"--frames", "1"}), &out), 0) << out;
  const std::string done = read_text(dir_ / "out.0001.exr");
  std::ofstream(dir_ / "out.0002.exr", std::ios::binary) << done.substr(0, done.size() / 2);  // cut short
  std::optional<io::FrameClaim> other = io::FrameClaim::take(dir_ / "out.0003.exr");  // another process's claim
  ASSERT_TRUE(other.has_value());
  EXPECT_EQ(run_cli(sequence({"--skip-existing", "--summary", (dir_ / "s.json").string()}), &out), 0) << out;
  EXPECT_TRUE(contains(out, "frame 1  skipped")) << out;
  EXPECT_TRUE(contains(out, "re-doing damaged frame")) << out;
  EXPECT_TRUE(contains(out, "frame 3  skipped: another process is denoising it")) << out;
  EXPECT_TRUE(io::exr_is_complete(dir_ / "out.0002.exr"));
  EXPECT_FALSE(fs::exists(dir_ / "out.0003.exr"));
  EXPECT_EQ(read_text(dir_ / "out.0001.exr"), done);
  EXPECT_TRUE(contains(read_text(dir_ / "s.json"), "claimed by another process")) << read_text(dir_ / "s.json");
  other.reset();
  EXPECT_FALSE(fs::exists(dir_ / ".out.0003.exr.residue-claim")) << "a claim leaves no file";
  std::ofstream(dir_ / "out.0003.exr");  // 0 bytes
  EXPECT_FALSE(io::exr_is_complete(dir_ / "out.0003.exr"));
  EXPECT_EQ(run_cli(sequence({"--skip-existing"}), &out), 0) << out;
  EXPECT_TRUE(io::exr_is_complete(dir_ / "out.0003.exr")) << out;
}

// Defect 22: eval on a sequence stopped at the first missing frame while denoise goes on; now both go on, say
// which frames they left out, and exit 3.
TEST_F(TrustSequenceCli, EvalGoesOnPastAMissingFrameAsDenoiseDoes) {
  fs::copy_file(kRoom / "noisy.exr", dir_ / "shot.0004.exr");
  for (const char* f : {"ref.0001.exr", "ref.0002.exr", "ref.0003.exr", "ref.0004.exr"})
    fs::copy_file(kRoom / "reference.exr", dir_ / f);
  std::string out;
  EXPECT_EQ(run_cli({"eval", (dir_ / "shot.####.exr").string(), "-r", (dir_ / "ref.####.exr").string(), "--frames", "1-4",
                     "--metrics-out", (dir_ / "m.json").string()}, &out), 3) << out;
  EXPECT_TRUE(contains(out, "frame 3  not scored")) << out;
  EXPECT_TRUE(contains(out, "1 of 4 frames not scored")) << out;
  const std::string json = read_text(dir_ / "m.json");
  EXPECT_TRUE(contains(json, "\"frames_scored\": 3")) << json;
  EXPECT_EQ(run_cli({"denoise", (dir_ / "shot.####.exr").string(), "-o", (dir_ / "out.####.exr").string(), "-m", "tiny",
                     "--frames", "1-4"}, &out), 3) << out;
  EXPECT_TRUE(fs::exists(dir_ / "out.0004.exr")) << "denoise went on past frame 3: " << out;
}

// Defect 11: one 37-byte "create 16384x16384x4" packet allocated 4.3 GB, with no cap across images or clients.
TEST(TrustIpc, LiveImagesStayWithinTheirMemory) {
  ipc::LiveImages images(size_t{1} << 20);  // 1 MiB: 65536 RGBA pixels
  const auto create = [](const std::string& name, int w, int h) {
    ipc::CreateImage c;
    c.name = name, c.width = w, c.height = h, c.channel_names = {"R", "G", "B", "A"};
    return c;
  };
  images.apply(create("a", 128, 128));  // 256 KiB
  images.apply(create("b", 256, 128));  // 512 KiB
  const std::string message = testing::error_message([&] { images.apply(create("huge", 16384, 16384)); }, ErrorKind::Input);
  EXPECT_TRUE(contains(message, "'huge' (16384 x 16384, 4 channels) needs 4096 MiB") && contains(message, "1 MiB in all"))
      << message;
  EXPECT_EQ(images.find("huge"), nullptr);
  EXPECT_TRUE(contains(testing::error_message([&] { images.apply(create("c", 128, 256)); }, ErrorKind::Input), "'c'"))
      << "768 KiB held: 512 more do not fit";
  images.apply(create("b", 256, 192));  // re-created: its old pixels are freed first (768 + 256 = 1 MiB)
  EXPECT_EQ(images.bytes(), size_t{1} << 20);
  EXPECT_TRUE(images.close("a"));
  images.apply(create("c", 128, 128));
  EXPECT_EQ(images.size(), 2u);
}

// Defect 12: farm slurm wrote free text into #SBATCH lines, merged an earlier submission's chunk summaries,
// accepted an unknown model or frames with no input, and called a --job-dir naming a file an internal error.
TEST_F(TrustSequenceCli, FarmSubmissionsAreCheckedBeforeAnyScriptIsWritten) {
  const std::string shot = (dir_ / "shot.####.exr").string(), outs = (dir_ / "out.####.exr").string();
  const auto farm = [&](const std::vector<std::string>& extra, std::string& out) {
    std::vector<std::string> args = {"farm", "slurm", shot, "-o", outs, "--dry-run"};
    args.insert(args.end(), extra.begin(), extra.end());
    return run_cli(args, &out);
  };
  std::string out;
  EXPECT_EQ(farm({"-m", "nosuch", "--job-dir", (dir_ / "j1").string()}, out), 3) << out;
  EXPECT_TRUE(contains(out, "no model \"nosuch\"")) << out;
  EXPECT_FALSE(fs::exists(dir_ / "j1")) << "nothing written for a job that cannot run";
  EXPECT_EQ(farm({"-m", "tiny", "--partition", "gpu\n#SBATCH --mem=1T"}, out), 2) << out;
  EXPECT_TRUE(contains(out, "a Slurm partition name")) << out;
  EXPECT_EQ(farm({"-m", "tiny", "--frames", "5000-5010"}, out), 3) << out;
  EXPECT_TRUE(contains(out, "none of the 11 frames")) << out;
  std::ofstream(dir_ / "afile");
  EXPECT_EQ(farm({"-m", "tiny", "--job-dir", (dir_ / "afile").string()}, out), 4) << out;
  EXPECT_TRUE(contains(out, "is a file, not a folder")) << out;
  const fs::path job = dir_ / "job%x";
  ASSERT_EQ(farm({"-m", "tiny", "--job-dir", job.string()}, out), 0) << out;
  EXPECT_TRUE(contains(read_text(job / "denoise.sbatch"), "#SBATCH --output=" + (dir_ / "job%%x").string() + "/logs/chunk_%a.log"))
      << "a literal % is written %% for Slurm: " << read_text(job / "denoise.sbatch");
  std::ofstream(job / "chunk_7.json") << "{\"frames\": []}";
  ASSERT_EQ(farm({"-m", "tiny", "--job-dir", job.string(), "--chunk", "1"}, out), 0) << out;
  EXPECT_TRUE(contains(out, "removed 1 summaries of an earlier submission")) << out;
  EXPECT_FALSE(fs::exists(job / "chunk_7.json"));
}

// --- extremes: finite output that scales with the input, whatever the tiling ---------------------------------

AovStack room() { return load_aov_stack({kRoom / "noisy.exr"}); }

void scale_colour(AovStack& s, float k) {
  for (size_t i = 0; i < s.color.image.size(); ++i) s.color.image.data()[i] *= k;
}

double max_rgb(const Image& im, int64_t x_end) {
  double m = 0;
  for (int64_t y = 0; y < im.height(); ++y)
    for (int64_t x = 0; x < x_end; ++x)
      for (int c = 0; c < 3; ++c) m = std::max(m, static_cast<double>(im.at(x, y, c)));
  return m;
}

int64_t non_finite(const Image& im) {
  int64_t n = 0;
  for (size_t i = 0; i < im.size(); ++i) n += !std::isfinite(im.data()[i]);
  return n;
}

class TrustExtremes : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override { model_ = nn::load_model(nn::find_model_for(GetParam(), FeatureSet::Full)); }
  Image run(const AovStack& s, int64_t tile = 0) const {
    DenoiseOptions o;
    o.tile = tile;
    return denoise(s, model_, o);
  }
  nn::Model model_;
};

// Defect 5: the room scaled by 1e-10 came out at up to 0.0147 (the network's bias on a black-looking input):
// every model sees the same image at any brightness, so the output scales with the input.
TEST_P(TrustExtremes, OutputScalesWithTheInput) {
  const AovStack s = room();
  const Image base = run(s);
  const double peak = max_rgb(base, base.width());
  for (const float k : {1e-30f, 1e-10f, 1e10f, 1e30f}) {
    AovStack scaled = s;
    scale_colour(scaled, k);
    const Image out = run(scaled);
    ASSERT_EQ(non_finite(out), 0) << "x" << k;
    double worst = 0;
    for (size_t i = 0; i < out.size(); i += 3)
      for (int c = 0; c < 3; ++c)
        worst = std::max(worst, std::abs(static_cast<double>(out.data()[i + c]) / k - base.data()[i + c]));
    EXPECT_LT(worst, 1e-4 * peak) << GetParam() << " at x" << k;
  }
}

// Defect 5: a black frame with one pixel of 1e-12 got 0.0147 of light 45 px away; the room with its left half
// exactly 0 got light there that --tile 32 (skipping empty tiles) did not.
TEST_P(TrustExtremes, BlackStaysBlackAndTheTilingChangesNothing) {
  AovStack one = room();
  std::fill(one.color.image.data(), one.color.image.data() + one.color.image.size(), 0.0f);
  for (int c = 0; c < 3; ++c) one.color.image.at(50, 50, c) = 1e-12f;
  EXPECT_LE(max_rgb(run(one), one.width()), 2e-12) << "never brighter than twice the brightest input";
  AovStack half = room();
  for (int64_t y = 0; y < half.height(); ++y)
    for (int64_t x = 0; x < 96; ++x)
      for (int c = 0; c < 3; ++c) half.color.image.at(x, y, c) = 0.0f;
  const Image whole = run(half), tiled = run(half, 32);
  for (size_t i = 0; i < whole.size(); ++i) ASSERT_EQ(whole.data()[i], tiled.data()[i]) << GetParam() << " value " << i;
}

// Defect 3: a block of 1e37-3e38 (finite, legal in a float EXR) gave thousands of NaN (the energy correction's
// sums overflowed) or +Inf (OIDN's inverse transfer).
TEST_P(TrustExtremes, ValuesNearTheFloatRangeGiveFiniteOutput) {
  AovStack s = room();
  for (int64_t y = 80; y < 100; ++y)
    for (int64_t x = 80; x < 100; ++x)
      for (int c = 0; c < 3; ++c) s.color.image.at(x, y, c) = 1e37f + 3e36f * static_cast<float>((x * 7 + y * 3 + c) % 97);
  EXPECT_EQ(non_finite(run(s)), 0) << GetParam();
  AovStack top = room();
  scale_colour(top, std::numeric_limits<float>::max() / static_cast<float>(max_rgb(top.color.image, top.width())));
  EXPECT_EQ(non_finite(run(top)), 0) << GetParam() << " with the brightest pixel at FLT_MAX";
}

INSTANTIATE_TEST_SUITE_P(Models, TrustExtremes, ::testing::Values("tiny", "multiscale", "oidn"),
                         [](const auto& p) { return p.param; });

}  // namespace
}  // namespace residue
