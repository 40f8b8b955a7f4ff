// Helpers shared by the test suites: temporary folders, paths to real data, small image builders.
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "core/aov/aov_stack.h"
#include "core/image/image.h"
#include "core/util/error.h"

namespace residue::testing {

// A fresh, empty folder under the system temp dir, removed when the object goes away.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// ../shared/datasets/... beside the checkout; empty path when the data set is not there.
std::filesystem::path shared_dataset(const std::string& relative);

// Open Image Denoise's weights as the repository ships them (resources/models/oidn).
std::filesystem::path oidn_dir();

// An image filled with deterministic pseudo-random values in [lo, hi).
Image random_image(int64_t width, int64_t height, int channels, unsigned seed, float lo = 0.0f,
                   float hi = 1.0f);

// A stack with every AOV (colour in [0, 4), albedo, camera-space normals, depth in [1, 10)), random but
// plausible values, named "test.exr".
AovStack random_stack(int64_t width, int64_t height, unsigned seed);

// The colour of an EXR as float (no reference search): for reading back what a test wrote.
Image read_exr_float(const std::filesystem::path& p);

// The message of the residue::Error that `f` throws; a test failure (and "") when it throws none or one of
// another kind.
std::string error_message(const std::function<void()>& f, ErrorKind kind);

// A file's whole content ("" when it cannot be read).
std::string read_text(const std::filesystem::path& p);

// Runs residue-cli with the given arguments; returns its exit code and captures stdout+stderr.
int run_cli(const std::vector<std::string>& args, std::string* output = nullptr);
// The same for any program.
int run_program(const std::string& program, const std::vector<std::string>& args, std::string* output = nullptr);

// residue-cli started in the background (posix_spawn), stdout and stderr going to `log`; killed (SIGKILL) and
// reaped if still running when the object goes away.
class ChildProcess {
 public:
  ChildProcess(const std::vector<std::string>& args, const std::filesystem::path& log);
  ~ChildProcess();
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  void signal(int sig);  // kill(pid, sig); also starts the clock wait() reads (0 only starts it)
  // Waits until the process has installed a handler for `sig` (its SigCgt mask in /proc), so that a signal sent
  // next meets the program's handling and not the default action; false after `timeout`.
  bool wait_until_handling(int sig, std::chrono::milliseconds timeout) const;
  // Whether the child has used `cpu_seconds` of CPU time (user + system, all its threads) within `timeout`: that
  // it is at work, however loaded the machine, where a wall-clock wait would only guess.
  bool wait_until_cpu(double cpu_seconds, std::chrono::milliseconds timeout) const;
  double wait();         // waits for the exit; the seconds since signal()
  int wait_status() const { return wait_status_; }  // waitpid's status, after wait()

 private:
  int pid_ = -1;
  int wait_status_ = 0;
  std::chrono::steady_clock::time_point signalled_;
};

}  // namespace residue::testing

// Skip the current test (with the reason printed) when a shared data set is missing.
#define RESIDUE_REQUIRE_SHARED(path)                                              \
  do {                                                                             \
    if ((path).empty()) GTEST_SKIP() << "shared data set not found beside the checkout"; \
  } while (0)
