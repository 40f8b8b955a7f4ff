// Frame sequences (issue 19): frame patterns and specs, and `residue-cli denoise shot.####.exr -o out.####.exr`
// end to end: every frame denoised with per-frame metrics, resumed after a kill without redoing finished frames,
// a failed frame not stopping the others, outputs checked before the first frame.
#include <signal.h>
#include <sys/wait.h>

#include <fstream>
#include <optional>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/aov/aov_loader.h"
#include "core/io/frame_claim.h"
#include "core/io/frame_sequence.h"
#include "support/exr_fixture.h"
#include "support/test_support.h"

namespace residue {
namespace {

namespace fs = std::filesystem;
using io::FramePattern;
using io::parse_frame_spec;
using testing::run_cli;
using testing::TempDir;

TEST(FramePattern, HashesAndPrintf) {
  const auto p = FramePattern::parse("renders/shot.####.exr");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->prefix, "renders/shot.");
  EXPECT_EQ(p->suffix, ".exr");
  EXPECT_EQ(p->path(42), "renders/shot.0042.exr");
  EXPECT_EQ(p->path(12345), "renders/shot.12345.exr") << "wider numbers are written as they are";
  EXPECT_EQ(p->frame_of("renders/shot.0042.exr"), 42);
  EXPECT_EQ(p->frame_of("renders/shot.042.exr"), std::nullopt) << "not how the pattern writes frame 42";
  EXPECT_EQ(p->frame_of("renders/shot.0042.exr.tmp"), std::nullopt);
  EXPECT_EQ(FramePattern::parse("a_%04d.exr")->path(7), "a_0007.exr");
  EXPECT_EQ(FramePattern::parse("a_%d.exr")->path(7), "a_7.exr");
  EXPECT_EQ(FramePattern::parse("a_%04d.exr")->to_string(), "a_####.exr");
  EXPECT_FALSE(FramePattern::parse("plain.exr"));
  EXPECT_FALSE(FramePattern::parse("take#2/plain.exr")) << "a '#' in a folder name is not a frame field";
  EXPECT_FALSE(FramePattern::parse("100%.exr"));
  EXPECT_NE(testing::error_message([] { FramePattern::parse("a.##.b.%04d.exr"); }, ErrorKind::Usage).find("more than one"),
            std::string::npos);
}

TEST(FramePattern, ANumberedFileNamesItsSequence) {
  const auto p = FramePattern::of_numbered_file("shots/s8007/noisy.0042.exr");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->to_string(), "shots/s8007/noisy.####.exr") << "the folder's digits are not the frame";
  EXPECT_EQ(p->frame_of("shots/s8007/noisy.0042.exr"), 42);
  EXPECT_EQ(p->path(1001), "shots/s8007/noisy.1001.exr");
  EXPECT_EQ(FramePattern::of_numbered_file("beauty_7.exr")->path(12), "beauty_12.exr") << "no padding: none added";
  EXPECT_EQ(FramePattern::of_numbered_file("v2/shot1001.exr")->to_string(), "v2/shot####.exr");
  EXPECT_FALSE(FramePattern::of_numbered_file("render/noisy.exr"));
  EXPECT_FALSE(FramePattern::of_numbered_file("noisy_20261202153000.exr")) << "14 digits: a time stamp, not a frame";
}

TEST(FrameSpec, RangesStepsAndLists) {
  EXPECT_EQ(parse_frame_spec("1001-1004"), (std::vector<int64_t>{1001, 1002, 1003, 1004}));
  EXPECT_EQ(parse_frame_spec("1001-1010x3"), (std::vector<int64_t>{1001, 1004, 1007, 1010}));
  EXPECT_EQ(parse_frame_spec("1,5,7-13:2"), (std::vector<int64_t>{1, 5, 7, 9, 11, 13}));
  EXPECT_EQ(parse_frame_spec("3,1-4"), (std::vector<int64_t>{3, 1, 2, 4})) << "in the order given, each once";
  EXPECT_EQ(parse_frame_spec("0"), (std::vector<int64_t>{0}));
  for (const char* bad : {"", "5-1", "1-5x0", "a", "1,,2", "-3", "1-", "1-5x", "1.5", "0-99999999"})
    EXPECT_FALSE(testing::error_message([&] { parse_frame_spec(bad); }, ErrorKind::Usage).empty()) << bad;
}

// `n` frames of a small noisy render (and their references), different per frame.
void write_frames(const fs::path& dir, int first, int n, int size) {
  for (int f = first; f < first + n; ++f) {
    auto value = [f](int x, int y, int c) {
      uint32_t h = (static_cast<uint32_t>(x) * 73856093u) ^ (static_cast<uint32_t>(y) * 19349663u) ^
                   (static_cast<uint32_t>(c + 3 * f) * 83492791u);
      h ^= h >> 13;
      h *= 0x5bd1e995u;
      h ^= h >> 15;
      return static_cast<float>(h & 0xffffu) / 65535.0f;
    };
    testing::FixturePart noisy, reference;
    noisy.width = noisy.height = reference.width = reference.height = size;
    const char* rgb[] = {"R", "G", "B"};
    for (int c = 0; c < 3; ++c) {
      noisy.channels.push_back({rgb[c], true, [=](int x, int y) { return 0.4f + 0.4f * (value(x, y, c) - 0.5f) + 0.002f * static_cast<float>(f); }});
      reference.channels.push_back({rgb[c], true, [=](int, int) { return 0.4f + 0.002f * static_cast<float>(f); }});
    }
    char name[64];
    std::snprintf(name, sizeof name, "shot.%04d.exr", f);
    testing::write_fixture_exr((dir / name).string(), {noisy});
    std::snprintf(name, sizeof name, "ref.%04d.exr", f);
    testing::write_fixture_exr((dir / name).string(), {reference});
  }
}

nlohmann::json read_json(const fs::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in);
}

std::vector<std::string> outputs_in(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

TEST(SequenceCli, FortyEightFramesWithMetricsInOneCommand) {
  TempDir dir;
  write_frames(dir.path(), 1001, 48, 32);
  fs::create_directory(dir / "out");
  std::string out;
  ASSERT_EQ(run_cli({"denoise", (dir / "shot.####.exr").string(), "-r", (dir / "ref.%04d.exr").string(), "-m", "base",
                     "-o", (dir / "out/den.####.exr").string(), "--summary", (dir / "summary.json").string()},
                    &out),
            0)
      << out;
  const auto j = read_json(dir / "summary.json");
  EXPECT_EQ(j["done"], 48);
  EXPECT_EQ(j["skipped"], 0);
  EXPECT_EQ(j["failed"], 0);
  EXPECT_EQ(j["exit_code"], 0);
  ASSERT_EQ(j["frames"].size(), 48u);
  for (const auto& f : j["frames"]) {
    EXPECT_EQ(f["status"], "done");
    EXPECT_LT(f["relmse"].get<double>(), f["noisy_relmse"].get<double>()) << f.dump();
  }
  EXPECT_EQ(j["frames"][7]["frame"], 1008);
  EXPECT_EQ(j["frames"][7]["output"], (dir / "out/den.1008.exr").string());
  // Each output is that frame's denoise, as a single-render run gives it.
  ASSERT_EQ(run_cli({"denoise", (dir / "shot.1008.exr").string(), "-m", "base", "-o", (dir / "single.exr").string()}, &out), 0);
  const Image a = testing::read_exr_float(dir / "out/den.1008.exr"), b = testing::read_exr_float(dir / "single.exr");
  ASSERT_EQ(a.size(), b.size());
  EXPECT_TRUE(std::equal(a.data(), a.data() + a.size(), b.data()));
}

TEST(SequenceCli, ExistingOutputsAreRefusedUpFrontSkippedOrReplaced) {
  TempDir dir;
  write_frames(dir.path(), 1, 4, 16);
  std::ofstream(dir / "out.0003.exr") << "mine";
  const std::vector<std::string> base = {"denoise", (dir / "shot.####.exr").string(), "-m", "base", "-o", (dir / "out.####.exr").string()};
  std::string out;
  EXPECT_EQ(run_cli(base, &out), 4) << out;
  EXPECT_NE(out.find("1 of the 4 outputs exist"), std::string::npos) << out;
  EXPECT_EQ(out.find("frame 1 "), std::string::npos) << "refused before the first frame: " << out;
  auto args = base;
  args.insert(args.end(), {"--skip-existing", "--summary", (dir / "s.json").string()});
  ASSERT_EQ(run_cli(args, &out), 0) << out;
  EXPECT_EQ(read_json(dir / "s.json")["skipped"], 1);
  std::ifstream mine(dir / "out.0003.exr");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(mine), {}), "mine") << "a skipped frame's file is left alone";
  args = base;
  args.push_back("--force");
  ASSERT_EQ(run_cli(args, &out), 0) << out;
  EXPECT_EQ(load_aov_stack({dir / "out.0003.exr"}).width(), 16);
  // A pattern in, a single file out is a usage error, and so is --frames for a single render.
  EXPECT_EQ(run_cli({"denoise", (dir / "shot.####.exr").string(), "-m", "base", "-o", (dir / "one.exr").string()}, &out), 2);
  EXPECT_NE(out.find("names no frame"), std::string::npos) << out;
  EXPECT_EQ(run_cli({"denoise", (dir / "shot.0001.exr").string(), "-m", "base", "-o", (dir / "one.exr").string(), "--frames", "1-3"}, &out), 2);
}

TEST(SequenceCli, AFailedFrameDoesNotStopTheOthersUnlessAsked) {
  TempDir dir;
  write_frames(dir.path(), 1, 5, 16);
  std::ofstream(dir / "shot.0003.exr", std::ios::trunc) << "not an EXR";
  std::string out;
  const std::vector<std::string> base = {"denoise", (dir / "shot.####.exr").string(), "-m", "base", "-o",
                                         (dir / "out.####.exr").string(), "--frames", "1-6", "--summary", (dir / "s.json").string()};
  EXPECT_EQ(run_cli(base, &out), 3) << out;
  auto j = read_json(dir / "s.json");
  EXPECT_EQ(j["done"], 4);
  EXPECT_EQ(j["failed"], 2) << "frame 3 (unreadable) and frame 6 (missing)";
  EXPECT_EQ(j["frames"][2]["status"], "failed");
  EXPECT_NE(j["frames"][2]["error"].get<std::string>().find("shot.0003.exr"), std::string::npos);
  EXPECT_NE(j["frames"][5]["error"].get<std::string>().find("does not exist"), std::string::npos);
  // Frames are read ahead and written behind the network, yet each frame's line comes in the frame's order (frame
  // 3's read failed while frame 2 was being written).
  size_t at = 0;
  for (const char* line : {"frame 1 ", "frame 2 ", "frame 3  failed", "frame 4 ", "frame 5 ", "frame 6  failed"}) {
    const size_t next = out.find(line, at);
    ASSERT_NE(next, std::string::npos) << "'" << line << "' after the line before it: " << out;
    at = next + 1;
  }
  for (const char* f : {"out.0001.exr", "out.0002.exr", "out.0004.exr", "out.0005.exr"}) EXPECT_TRUE(fs::exists(dir / f)) << f;
  for (const char* f : {"out.0001.exr", "out.0002.exr", "out.0004.exr", "out.0005.exr"}) fs::remove(dir / f);
  auto args = base;
  args.push_back("--fail-fast");
  args.push_back("--force");
  EXPECT_EQ(run_cli(args, &out), 3) << out;
  j = read_json(dir / "s.json");
  EXPECT_EQ(j["done"], 2);
  EXPECT_EQ(j["frames"][3]["status"], "pending") << "not reached";
  EXPECT_FALSE(fs::exists(dir / "out.0004.exr"));
}

// SIGINT while a frame is denoised (the frame before it written meanwhile, on the background thread): the run
// stops within that frame, keeps every frame it finished whole, says which frame it stopped in, and leaves no
// temporary file or claim behind.
TEST(SequenceCli, AnInterruptKeepsTheFramesFinishedBeforeIt) {
  TempDir dir;
  write_frames(dir.path(), 1, 4, 768);
  const fs::path log = fs::temp_directory_path() / ("residue-seq-int-" + std::to_string(::getpid()) + ".log");
  const std::vector<std::string> args = {"denoise", (dir / "shot.####.exr").string(), "-m", "base", "-o",
                                         (dir / "out.####.exr").string(), "--backend", "eigen", "--summary",
                                         (dir / "s.json").string()};
  int status = 0;
  {
    testing::ChildProcess child(args, log);
    ASSERT_TRUE(child.wait_until_handling(SIGINT, std::chrono::seconds(60)));
    // Frame 1 is written while frame 2 is denoised: its file appears a moment into frame 2 (seconds of work).
    for (int i = 0; i < 4800 && !fs::exists(dir / "out.0001.exr"); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(25));
    ASSERT_TRUE(fs::exists(dir / "out.0001.exr")) << testing::read_text(log);
    child.signal(SIGINT);
    child.wait();
    status = child.wait_status();
  }
  const std::string text = testing::read_text(log);
  fs::remove(log);
  ASSERT_TRUE(WIFEXITED(status)) << text;
  EXPECT_EQ(WEXITSTATUS(status), 130) << text;
  const auto j = read_json(dir / "s.json");
  EXPECT_EQ(j["exit_code"], 130);
  ASSERT_EQ(j["frames"].size(), 4u);
  EXPECT_EQ(j["frames"][0]["status"], "done") << text;
  size_t stopped = 0;  // the frame the signal came in: whole outputs before it, nothing from it on
  while (stopped < 4 && j["frames"][stopped]["status"] == "done") {
    EXPECT_EQ(load_aov_stack({j["frames"][stopped]["output"].get<std::string>()}).width(), 768) << stopped;
    ++stopped;
  }
  ASSERT_LT(stopped, 4u) << "the signal came before the end: " << text;
  EXPECT_EQ(j["frames"][stopped]["status"], "interrupted") << text;
  for (size_t f = stopped; f < 4; ++f) {
    EXPECT_FALSE(fs::exists(j["frames"][f]["output"].get<std::string>())) << f;
    if (f > stopped) {
      EXPECT_EQ(j["frames"][f]["status"], "pending");
    }
  }
  for (const auto& name : outputs_in(dir.path())) EXPECT_NE(name.front(), '.') << name << " was left behind";
}

// A run killed between writing a frame and removing its claim leaves the claim file beside a finished frame.
// The next run skips that frame and removes the stale claim; a claim a live process holds stays.
TEST(SequenceCli, AStaleClaimBesideAFinishedFrameIsRemoved) {
  TempDir dir;
  write_frames(dir.path(), 1, 3, 32);
  std::vector<std::string> args = {"denoise", (dir / "shot.####.exr").string(), "-m", "bilateral", "-o",
                                   (dir / "out.####.exr").string()};
  std::string out;
  ASSERT_EQ(run_cli(args, &out), 0) << out;
  std::ofstream(dir / ".out.0001.exr.residue-claim") << "";  // as a killed run leaves it
  std::optional<io::FrameClaim> held = io::FrameClaim::take(dir / "out.0002.exr");  // a live process's
  ASSERT_TRUE(held.has_value());
  args.push_back("--skip-existing");
  ASSERT_EQ(run_cli(args, &out), 0) << out;
  EXPECT_FALSE(fs::exists(dir / ".out.0001.exr.residue-claim")) << "the stale claim was removed";
  EXPECT_TRUE(fs::exists(dir / ".out.0002.exr.residue-claim")) << "a held claim is its owner's";
  held.reset();
  EXPECT_FALSE(fs::exists(dir / ".out.0002.exr.residue-claim"));
}

// A run killed (SIGKILL) part-way leaves only complete frames; the rerun with --skip-existing denoises the rest
// and leaves the finished ones untouched.
TEST(SequenceCli, ResumesAfterAKillWithoutRedoingFinishedFrames) {
  TempDir dir;
  write_frames(dir.path(), 1, 48, 96);
  const fs::path log = fs::temp_directory_path() / ("residue-seq-" + std::to_string(::getpid()) + ".log");
  std::vector<std::string> args = {"denoise", (dir / "shot.####.exr").string(), "-m", "base", "-o",
                                   (dir / "out.####.exr").string(), "--backend", "eigen"};
  {
    testing::ChildProcess child(args, log);
    auto finished = [&] {
      int n = 0;
      for (const auto& name : outputs_in(dir.path())) n += name.rfind("out.", 0) == 0;
      return n;
    };
    for (int i = 0; i < 1200 && finished() < 5; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(25));
    child.signal(SIGKILL);
    child.wait();
  }
  fs::remove(log);
  std::map<std::string, fs::file_time_type> before;
  for (const auto& name : outputs_in(dir.path()))
    if (name.rfind("out.", 0) == 0) {
      EXPECT_EQ(load_aov_stack({dir / name}).width(), 96) << name << " is complete";
      before[name] = fs::last_write_time(dir / name);
    }
  ASSERT_GE(before.size(), 5u);
  ASSERT_LT(before.size(), 48u) << "the kill came before the end";
  args.insert(args.end(), {"--skip-existing", "--summary", (dir / "s.json").string()});
  std::string out;
  ASSERT_EQ(run_cli(args, &out), 0) << out;
  const auto j = read_json(dir / "s.json");
  EXPECT_EQ(j["skipped"].get<size_t>(), before.size());
  EXPECT_EQ(j["done"].get<size_t>(), 48 - before.size());
  for (const auto& [name, time] : before) EXPECT_EQ(fs::last_write_time(dir / name), time) << name << " was not redone";
  size_t outputs = 0, hidden = 0;
  for (const auto& name : outputs_in(dir.path())) {
    outputs += name.rfind("out.", 0) == 0;
    hidden += name.front() == '.';
  }
  EXPECT_EQ(outputs, 48u);
  EXPECT_EQ(hidden, 0u) << "the killed run's temporary file was removed by the rerun";
}

}  // namespace
}  // namespace residue
