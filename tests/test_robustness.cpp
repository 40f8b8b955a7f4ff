// Bad input, interrupted runs and outputs that cannot be written: each case of issue 18 that is not a loader or a
// model-file case (those live in test_aov / test_denoise / test_tza), end to end where the user meets it.
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <atomic>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoise_job.h"
#include "core/denoise/denoiser.h"
#include "core/io/atomic_file.h"
#include "core/io/exr_writer.h"
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

// Files in `dir` (hidden ones included), by name.
std::vector<std::string> files_in(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// A plain multilayer render (R,G,B, albedo, normal, depth) of size x size with a noisy-looking colour.
void write_render(const fs::path& path, int size) {
  auto hash = [](int x, int y, int c) {
    uint32_t h = (static_cast<uint32_t>(x) * 73856093u) ^ (static_cast<uint32_t>(y) * 19349663u) ^ (static_cast<uint32_t>(c) * 83492791u);
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    return static_cast<float>(h & 0xffffu) / 65535.0f;
  };
  testing::FixturePart part;
  part.width = part.height = size;
  int c = 0;
  for (const char* name : {"R", "G", "B"}) part.channels.push_back({name, true, [&hash, c](int x, int y) { return 2.0f * hash(x, y, c); }}), ++c;
  for (const char* name : {"albedo.R", "albedo.G", "albedo.B"}) part.channels.push_back({name, true, [](int, int) { return 0.5f; }});
  part.channels.push_back({"normal.X", true, [](int, int) { return 0.0f; }});
  part.channels.push_back({"normal.Y", true, [](int, int) { return 0.0f; }});
  part.channels.push_back({"normal.Z", true, [](int, int) { return 1.0f; }});
  part.channels.push_back({"depth.Z", false, [](int x, int) { return 2.0f + 0.01f * static_cast<float>(x); }});
  testing::write_fixture_exr(path.string(), {part});
}

// --- outputs: every check before any work -------------------------------------------------------------------

class OutputChecks : public ::testing::Test {
 protected:
  void SetUp() override { render_ = dir_ / "render.exr", write_render(render_, 64); }
  // Runs a denoise that must fail at once with `code`, saying `says`, and leave the folder as it was.
  void expect_refused(const std::vector<std::string>& extra, int code, const std::string& says) {
    const auto before = files_in(dir_.path());
    std::vector<std::string> args = {"denoise", render_.string(), "-m", "small"};
    args.insert(args.end(), extra.begin(), extra.end());
    std::string out;
    EXPECT_EQ(run_cli(args, &out), code) << out;
    EXPECT_NE(out.find(says), std::string::npos) << out;
    EXPECT_EQ(out.find("tiles"), std::string::npos) << "refused before any tile ran: " << out;
    EXPECT_EQ(files_in(dir_.path()), before) << out;
  }
  TempDir dir_;
  fs::path render_;
};

TEST_F(OutputChecks, MissingFolder) { expect_refused({"-o", (dir_ / "no/such/out.exr").string()}, 4, "does not exist"); }

TEST_F(OutputChecks, PathEndingInSlash) { expect_refused({"-o", (dir_ / "out.exr/").string()}, 4, "is not a file name"); }

TEST_F(OutputChecks, FolderAsOutput) {
  fs::create_directory(dir_ / "sub.exr");
  expect_refused({"-o", (dir_ / "sub.exr").string(), "--force"}, 4, "is a folder");
}

TEST_F(OutputChecks, UnknownCompression) {
  expect_refused({"-o", (dir_ / "out.exr").string(), "--compression", "bogus"}, 2, "unknown EXR compression 'bogus'");
}

TEST_F(OutputChecks, NotAnExrName) { expect_refused({"-o", (dir_ / "out.png").string()}, 4, "ending in .exr"); }

TEST_F(OutputChecks, ExistingWithoutForce) {
  std::ofstream(dir_ / "out.exr") << "mine";
  expect_refused({"-o", (dir_ / "out.exr").string()}, 4, "exists; pass --force");
  EXPECT_EQ(read_text(dir_ / "out.exr"), "mine");
}

TEST_F(OutputChecks, TheInputItselfEvenWithForce) {
  const std::string before = read_text(render_);
  expect_refused({"-o", render_.string(), "--force"}, 4, "would lose the render");
  EXPECT_EQ(read_text(render_), before) << "the render and its AOVs are untouched";
  // The same file under another spelling of its path.
  expect_refused({"-o", (dir_.path() / "." / "render.exr").string(), "--force"}, 4, "would lose the render");
}

TEST_F(OutputChecks, ReadOnlyFolder) {
  if (::geteuid() == 0) GTEST_SKIP() << "root may write anywhere";
  fs::create_directory(dir_ / "ro");
  fs::permissions(dir_ / "ro", fs::perms::owner_read | fs::perms::owner_exec);
  expect_refused({"-o", (dir_ / "ro/out.exr").string()}, 4, "is not writable");
  fs::permissions(dir_ / "ro", fs::perms::owner_all);
}

TEST_F(OutputChecks, EvalMetricsFileCheckedBeforeScoring) {
  std::string out;
  EXPECT_EQ(run_cli({"eval", render_.string(), "-r", render_.string(), "--metrics-out", (dir_ / "m.txt").string()}, &out), 2)
      << out;
  EXPECT_NE(out.find("must end in .json or .csv"), std::string::npos) << out;
  std::ofstream(dir_ / "m.json") << "{}";
  EXPECT_EQ(run_cli({"eval", render_.string(), "-r", render_.string(), "--metrics-out", (dir_ / "m.json").string()}, &out), 4)
      << out;
  EXPECT_EQ(read_text(dir_ / "m.json"), "{}");
}

// --- temporary files ------------------------------------------------------------------------------------------

// A pid that no process has: a child that has exited and been reaped.
pid_t dead_pid() {
  const pid_t pid = ::fork();
  if (pid == 0) ::_exit(0);
  ::waitpid(pid, nullptr, 0);
  return pid;
}

std::string host() {
  char name[256] = {};
  ::gethostname(name, sizeof(name) - 1);
  return name;
}

TEST(TempFiles, AbandonedOnesOfThisOutputAreRemovedOthersKept) {
  TempDir dir;
  const fs::path out = dir / "out.exr";
  const std::string dead = ".out.exr.residue-tmp-" + host() + "-" + std::to_string(dead_pid()) + "-abcdef.exr";
  const std::string alive = ".out.exr.residue-tmp-" + host() + "-" + std::to_string(::getppid()) + "-abcdef.exr";
  const std::string other_host = ".out.exr.residue-tmp-some-other-host-" + std::to_string(dead_pid()) + "-abcdef.exr";
  const std::string other_output = ".b.exr.residue-tmp-" + host() + "-" + std::to_string(dead_pid()) + "-abcdef.exr";
  for (const auto& n : {dead, alive, other_host, other_output}) std::ofstream(dir / n) << "partial";
  const auto removed = io::prepare_output(out, false);
  ASSERT_EQ(removed.size(), 1u);
  EXPECT_EQ(removed[0].filename(), dead);
  std::vector<std::string> kept = {alive, other_host, other_output};
  std::sort(kept.begin(), kept.end());
  EXPECT_EQ(files_in(dir.path()), kept) << "a live writer's, another machine's and another output's temporary files stay";
}

TEST(TempFiles, InProgressOnesAreRemovedOnRequest) {
  TempDir dir;
  const std::string message = testing::error_message(
      [&] {
        io::write_atomically(dir / "out.exr", false, [&](const fs::path& temp) {
          std::ofstream(temp) << "half written";
          EXPECT_TRUE(fs::exists(temp));
          EXPECT_NE(temp.filename().string().find("-" + std::to_string(::getpid()) + "-"), std::string::npos)
              << "the name says which process writes it: " << temp;
          io::remove_temp_files_in_progress();  // what the signal watchdog does before exiting
          EXPECT_FALSE(fs::exists(temp));
        });
      },
      ErrorKind::Output);
  EXPECT_NE(message.find("disappeared"), std::string::npos) << message;
  EXPECT_TRUE(files_in(dir.path()).empty());
}

// --- cancellation inside a tile -------------------------------------------------------------------------------

// The paper's 16/128 network on one 384x384 tile: seconds of work in a single tile. The cancel comes once the
// worker has looked at the token inside the tile's layers (the tile runner looks once before the tile starts).
void expect_cancel_inside_one_tile(const std::string& backend) {
  if (backend == "onednn" && nn::available_backends().back() != "onednn") GTEST_SKIP() << "built without oneDNN";
  const AovStack stack = testing::random_stack(384, 384, 3);
  const nn::Model model = nn::load_model(nn::find_model_for("paper", FeatureSet::Full));
  CancelToken token;
  DenoiseOptions options;
  options.backend = backend;
  options.tile = 512;
  options.cancel = &token;
  std::atomic<int> tiles{0};
  std::atomic<bool> cancelled{false};
  std::thread worker([&] {
    try {
      denoise(stack, model, options, [&](const TileEvent&, const Image&) { return ++tiles > 0; });
    } catch (const Cancelled&) {
      cancelled = true;
    }
  });
  while (token.checks() < 3) std::this_thread::yield();  // inside the tile: past its first layer
  EXPECT_EQ(tiles.load(), 0) << "the only tile is still running";
  token.request();
  worker.join();
  EXPECT_TRUE(cancelled.load());
  EXPECT_EQ(tiles.load(), 0) << "stopped inside the only tile, not after it";
}

TEST(Cancel, EigenStopsInsideATile) { expect_cancel_inside_one_tile("eigen"); }
TEST(Cancel, OneDnnStopsInsideATile) { expect_cancel_inside_one_tile("onednn"); }

TEST(Cancel, ARaisedTokenStopsBeforeAnyTile) {
  CancelToken token;
  token.request();
  DenoiseOptions options;
  options.cancel = &token;
  const nn::Model model = nn::load_model(nn::find_model_for("tiny", FeatureSet::Full));
  int tiles = 0;
  EXPECT_THROW(denoise(testing::random_stack(32, 32, 1), model, options, [&](const TileEvent&, const Image&) { return ++tiles > 0; }),
               Cancelled);
  EXPECT_EQ(tiles, 0);
}

// --- signals ------------------------------------------------------------------------------------------------

struct SignalCase {
  int signal;
  int exit_code;
  std::string backend;
  bool streamed;
};

class Signals : public ::testing::TestWithParam<SignalCase> {};

// The arguments of a denoise with `paper` that runs for tens of seconds: one 768x768 tile in memory, or, streamed,
// 64-pixel tiles of a 1024x1024 render (54 MB) within 40 MiB.
std::vector<std::string> long_denoise(const TempDir& dir, bool streamed) {
  write_render(dir / "render.exr", streamed ? 1024 : 768);
  std::vector<std::string> args = {"denoise", (dir / "render.exr").string(), "-m", "paper", "-o", (dir / "out.exr").string()};
  if (streamed) args.insert(args.end(), {"--tile", "64", "--max-memory", "40"});
  else args.insert(args.end(), {"--tile", "1024"});
  return args;
}

// SIGINT / SIGTERM / SIGHUP once the run is at work must stop it (in memory: inside its only tile), exit 130 / 143 and leave
// the folder as it was (no output, no temporary file). The time it took is printed (measured, not asserted;
// docs/RELIABILITY.md).
TEST_P(Signals, StopInsideTheTileAndLeaveNoFile) {
  const SignalCase c = GetParam();
  if (c.backend == "onednn" && nn::available_backends().back() != "onednn") GTEST_SKIP() << "built without oneDNN";
  TempDir dir;
  std::vector<std::string> args = long_denoise(dir, c.streamed);
  args.insert(args.end(), {"--backend", c.backend});
  const auto before = files_in(dir.path());
  const fs::path log = fs::temp_directory_path() / ("residue-signal-" + std::to_string(::getpid()) + ".log");
  testing::ChildProcess child(args, log);
  // Streamed runs create their (temporary) output before the first tile: wait for it, then signal.
  for (int i = 0; i < 200 && c.streamed; ++i) {
    if (files_in(dir.path()).size() > before.size()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  // Once the handler is in place (a loaded machine may take seconds to get there) and the child is at work: 3 s
  // of CPU time, past loading (well under 1 s) and inside the tile (about 30 CPU-seconds of `paper` at 768 px).
  ASSERT_TRUE(child.wait_until_handling(c.signal, std::chrono::seconds(60)));
  ASSERT_TRUE(child.wait_until_cpu(3.0, std::chrono::seconds(120))) << read_text(log);
  child.signal(c.signal);
  const double seconds = child.wait();
  const std::string text = read_text(log);
  fs::remove(log);
  std::printf("[ measured ] %s on %s%s: stopped %.2f s after the signal\n", strsignal(c.signal), c.backend.c_str(),
              c.streamed ? " (streamed)" : "", seconds);
  ASSERT_TRUE(WIFEXITED(child.wait_status())) << "ended by the signal itself, not by the handler: " << text;
  EXPECT_EQ(WEXITSTATUS(child.wait_status()), c.exit_code) << text;
  if (!c.streamed) {
    EXPECT_EQ(text.find("1/1 tiles"), std::string::npos) << "the only tile did not finish: " << text;
  }
  EXPECT_NE(text.find("interrupted"), std::string::npos) << text;
  EXPECT_EQ(files_in(dir.path()), before) << text;
}

INSTANTIATE_TEST_SUITE_P(Cli, Signals,
                         ::testing::Values(SignalCase{SIGINT, 130, "eigen", false}, SignalCase{SIGTERM, 143, "eigen", false},
                                           SignalCase{SIGTERM, 143, "onednn", false}, SignalCase{SIGINT, 130, "eigen", true},
                                           // A dropped ssh session (issue 49, 18): handled as SIGTERM is.
                                           SignalCase{SIGHUP, 129, "eigen", true}),
                         [](const ::testing::TestParamInfo<SignalCase>& p) {
                           const int s = p.param.signal;
                           return std::string(s == SIGINT ? "Sigint" : s == SIGTERM ? "Sigterm" : "Sighup") + "_" + p.param.backend +
                                  (p.param.streamed ? "_streamed" : "");
                         });

// SIGKILL cannot be handled: the streamed run's temporary file stays, named for its process; the next run on the
// same output sees that process is gone, removes the file and says so.
TEST(SignalsKill, TheNextRunRemovesTheTemporaryFile) {
  TempDir dir;
  const std::vector<std::string> args = long_denoise(dir, true);
  const fs::path log = fs::temp_directory_path() / ("residue-kill-" + std::to_string(::getpid()) + ".log");
  std::string temp;
  {
    testing::ChildProcess child(args, log);
    for (int i = 0; i < 400 && temp.empty(); ++i) {
      for (const auto& n : files_in(dir.path()))
        if (n.rfind(".out.exr.residue-tmp-", 0) == 0) temp = n;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    child.signal(SIGKILL);
    child.wait();
  }
  fs::remove(log);
  ASSERT_FALSE(temp.empty()) << "the streamed run writes into a temporary file from the start";
  EXPECT_NE(temp.find("-" + host() + "-"), std::string::npos) << temp;
  ASSERT_TRUE(fs::exists(dir / temp));
  std::string out;
  ASSERT_EQ(run_cli({"denoise", (dir / "render.exr").string(), "-m", "bilateral", "-o", (dir / "out.exr").string()}, &out), 0)
      << out;
  EXPECT_NE(out.find("removed '" + (dir / temp).string() + "'"), std::string::npos) << out;
  EXPECT_EQ(files_in(dir.path()), (std::vector<std::string>{"out.exr", "render.exr"}));
}

// An output that another program creates while the denoise runs is found at the next tile, not after the work,
// and is left as that program wrote it.
TEST(OutputRace, CreatedDuringTheDenoiseStopsItAtTheNextTile) {
  TempDir dir;
  const std::vector<std::string> args = long_denoise(dir, true);
  const fs::path log = fs::temp_directory_path() / ("residue-race-" + std::to_string(::getpid()) + ".log");
  testing::ChildProcess child(args, log);
  for (int i = 0; i < 400 && files_in(dir.path()).size() < 2; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  child.signal(0);  // starts the clock
  std::ofstream(dir / "out.exr") << "theirs";
  const double seconds = child.wait();
  const std::string text = read_text(log);
  fs::remove(log);
  std::printf("[ measured ] stopped %.2f s after the output appeared\n", seconds);
  ASSERT_TRUE(WIFEXITED(child.wait_status())) << text;
  EXPECT_EQ(WEXITSTATUS(child.wait_status()), 4) << text;
  EXPECT_NE(text.find("was created by another program during the denoise"), std::string::npos) << text;
  EXPECT_EQ(read_text(dir / "out.exr"), "theirs");
  EXPECT_EQ(files_in(dir.path()), (std::vector<std::string>{"out.exr", "render.exr"})) << "no temporary file left";
}

// --- inputs ---------------------------------------------------------------------------------------------------

// A reference whose data window covers half of the image: the other half is not scored (excluded and counted),
// and the scores equal those of the covered half scored alone.
TEST(ReferenceWindow, UncoveredPixelsAreExcludedNotBlack) {
  TempDir dir;
  auto value = [](int x, int y) { return 0.25f + 0.01f * static_cast<float>((x * 7 + y * 3) % 50); };
  testing::FixturePart noisy;
  noisy.width = noisy.height = 32;
  for (const char* n : {"R", "G", "B"}) noisy.channels.push_back({n, false, [&](int x, int y) { return value(x, y) * 1.2f; }});
  testing::write_fixture_exr((dir / "noisy.exr").string(), {noisy});
  testing::FixturePart ref = noisy;
  ref.channels.clear();
  for (const char* n : {"R", "G", "B"}) ref.channels.push_back({n, false, value});
  ref.full_width = ref.full_height = 32;
  ref.width = 16;  // the left half
  testing::write_fixture_exr((dir / "ref.exr").string(), {ref});
  testing::FixturePart crop = noisy;
  crop.width = 16;
  testing::write_fixture_exr((dir / "noisy_left.exr").string(), {crop});
  ref.full_width = 16;
  testing::write_fixture_exr((dir / "ref_left.exr").string(), {ref});

  std::string out;
  ASSERT_EQ(run_cli({"eval", "--json", (dir / "noisy.exr").string(), "-r", (dir / "ref.exr").string()}, &out), 0) << out;
  const auto j = nlohmann::json::parse(out);
  EXPECT_NE(j["notes"].dump().find("not scored"), std::string::npos) << "a note says so: " << out;
  std::string out_left;
  ASSERT_EQ(run_cli({"eval", "--json", (dir / "noisy_left.exr").string(), "-r", (dir / "ref_left.exr").string()}, &out_left), 0);
  const auto left = nlohmann::json::parse(out_left);
  EXPECT_EQ(j["rows"][0]["excluded_reference"].get<int64_t>(), 16 * 32);
  EXPECT_EQ(j["rows"][0]["pixels"].get<int64_t>(), 16 * 32);
  EXPECT_NEAR(j["rows"][0]["relmse"].get<double>(), left["rows"][0]["relmse"].get<double>(), 1e-12);
  EXPECT_LT(j["rows"][0]["relmse"].get<double>(), 0.1) << "not scored against black";
}

TEST(InputFormat, PngNamedExrIsRefusedNamingTheFormat) {
  TempDir dir;
  testing::FixturePart part;
  part.width = part.height = 8;
  for (const char* n : {"R", "G", "B"}) part.channels.push_back(testing::constant_channel(n, 0.5f));
  testing::write_fixture_exr((dir / "real.exr").string(), {part});
  std::string out;
  ASSERT_EQ(testing::run_program("oiiotool", {(dir / "real.exr").string(), "-d", "uint8", "-o", (dir / "img.png").string()}, &out), 0)
      << out;
  fs::rename(dir / "img.png", dir / "render.exr");
  const std::string message = testing::error_message([&] { load_aov_stack({dir / "render.exr"}); }, ErrorKind::Input);
  EXPECT_NE(message.find("is a png file, not OpenEXR"), std::string::npos) << message;
  EXPECT_EQ(run_cli({"info", (dir / "render.exr").string()}, &out), 3) << out;
}

// An albedo with one channel missing is not used, and the loader (and the CLI, before denoising with a
// colour-only model) says which channels it found.
TEST(InputAovs, IncompleteAlbedoIsNamed) {
  TempDir dir;
  testing::FixturePart part;
  part.width = part.height = 16;
  for (const char* n : {"R", "G", "B", "albedo.R", "albedo.G", "normal.X", "normal.Y", "normal.Z", "depth.Z"})
    part.channels.push_back(testing::constant_channel(n, 0.5f));
  testing::write_fixture_exr((dir / "render.exr").string(), {part});
  const AovStack stack = load_aov_stack({dir / "render.exr"});
  EXPECT_FALSE(stack.albedo.has_value());
  bool named = false;
  for (const auto& n : stack.notes) named |= n.find("albedo pass has only albedo.R, albedo.G") != std::string::npos;
  EXPECT_TRUE(named) << ::testing::PrintToString(stack.notes);
  std::string out;
  ASSERT_EQ(run_cli({"denoise", (dir / "render.exr").string(), "-m", "base", "-o", (dir / "out.exr").string()}, &out), 0) << out;
  EXPECT_NE(out.find("note: the albedo pass has only albedo.R, albedo.G"), std::string::npos) << out;
  EXPECT_NE(out.find("base-color"), std::string::npos) << "the colour-only variant ran: " << out;
}

}  // namespace
}  // namespace residue
