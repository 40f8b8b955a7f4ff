#include "support/test_support.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <fstream>
#include <iterator>
#include <sstream>
#include <thread>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "core/aov/aov_loader.h"

extern char** environ;

namespace residue::testing {

TempDir::TempDir() {
  std::string templ = (std::filesystem::temp_directory_path() / "residue-test-XXXXXX").string();
  if (!mkdtemp(templ.data())) throw std::runtime_error("cannot create a temporary folder");
  path_ = templ;
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

std::filesystem::path shared_dataset(const std::string& relative) {
  std::filesystem::path p = std::filesystem::path(RESIDUE_SHARED_DIR) / "datasets" / relative;
  return std::filesystem::exists(p) ? p : std::filesystem::path();
}

std::filesystem::path oidn_dir() {
  return std::filesystem::path(RESIDUE_TEST_FIXTURES).parent_path().parent_path() / "resources" / "models" / "oidn";
}

Image random_image(int64_t width, int64_t height, int channels, unsigned seed, float lo, float hi) {
  Image img(width, height, channels);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> dist(lo, hi);
  for (size_t i = 0; i < img.size(); ++i) img.data()[i] = dist(rng);
  return img;
}

AovStack random_stack(int64_t w, int64_t h, unsigned seed) {
  AovStack s;
  s.convention = "test";
  s.color.image = random_image(w, h, 3, seed, 0.0f, 4.0f);
  s.color.source.file = "test.exr";
  s.albedo = Aov{random_image(w, h, 3, seed + 1, 0.0f, 1.0f), {}, {}, 0};
  s.normal = Aov{random_image(w, h, 3, seed + 2, -1.0f, 1.0f), {}, {}, 0};
  s.depth = Aov{random_image(w, h, 1, seed + 3, 1.0f, 10.0f), {}, {}, 0};
  s.normal_space = NormalSpace::Camera;
  s.data_window = {0, 0, w, h};
  s.display_width = w;
  s.display_height = h;
  return s;
}

static std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) {
    if (c == '\'') out += "'\\''";
    else out += c;
  }
  return out + "'";
}

Image read_exr_float(const std::filesystem::path& p) {
  LoadOptions lo;
  lo.load_reference = false;
  return load_aov_stack({p}, lo).color.image;
}

std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

int run_cli(const std::vector<std::string>& args, std::string* output) { return run_program(RESIDUE_CLI_PATH, args, output); }

int run_program(const std::string& program, const std::vector<std::string>& args, std::string* output) {
  std::string cmd = shell_quote(program);
  for (const auto& a : args) cmd += " " + shell_quote(a);
  cmd += " 2>&1 </dev/null";
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) throw std::runtime_error("cannot run " + cmd);
  std::array<char, 4096> buf{};
  std::string text;
  size_t n = 0;
  while ((n = fread(buf.data(), 1, buf.size(), pipe)) > 0) text.append(buf.data(), n);
  int status = pclose(pipe);
  if (output) *output = text;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

ChildProcess::ChildProcess(const std::vector<std::string>& args, const std::filesystem::path& log) {
  std::vector<std::string> argv_s = {RESIDUE_CLI_PATH};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  pid_t pid = -1;
  EXPECT_EQ(posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ), 0);
  pid_ = pid;
  posix_spawn_file_actions_destroy(&actions);
  signalled_ = std::chrono::steady_clock::now();
}

ChildProcess::~ChildProcess() {
  if (pid_ > 0) {
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
  }
}

void ChildProcess::signal(int sig) {
  signalled_ = std::chrono::steady_clock::now();
  if (pid_ > 0) ::kill(pid_, sig);
}

bool ChildProcess::wait_until_handling(int sig, std::chrono::milliseconds timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (pid_ > 0 && std::chrono::steady_clock::now() < deadline) {
    std::ifstream status("/proc/" + std::to_string(pid_) + "/status");
    for (std::string line; std::getline(status, line);)
      if (line.rfind("SigCgt:", 0) == 0 && (std::stoull(line.substr(7), nullptr, 16) >> (sig - 1) & 1u) != 0) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

bool ChildProcess::wait_until_cpu(double cpu_seconds, std::chrono::milliseconds timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  const double tick = static_cast<double>(::sysconf(_SC_CLK_TCK));
  while (pid_ > 0 && std::chrono::steady_clock::now() < deadline) {
    std::ifstream stat("/proc/" + std::to_string(pid_) + "/stat");
    std::string text((std::istreambuf_iterator<char>(stat)), std::istreambuf_iterator<char>());
    // Fields after the command name (which may hold spaces, so it is skipped to its closing parenthesis):
    // state is field 3, utime 14, stime 15.
    const size_t close = text.rfind(')');
    if (close == std::string::npos) return false;  // the process is gone
    std::istringstream fields(text.substr(close + 2));
    std::string field;
    unsigned long long utime = 0, stime = 0;
    for (int i = 3; i <= 15 && fields >> field; ++i) {
      if (i == 14) utime = std::stoull(field);
      if (i == 15) stime = std::stoull(field);
    }
    if (static_cast<double>(utime + stime) / tick >= cpu_seconds) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

double ChildProcess::wait() {
  if (pid_ > 0) ::waitpid(pid_, &wait_status_, 0);
  pid_ = -1;
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - signalled_).count();
}

std::string error_message(const std::function<void()>& f, ErrorKind kind) {
  try {
    f();
  } catch (const Error& e) {
    EXPECT_EQ(static_cast<int>(e.kind()), static_cast<int>(kind)) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "no residue::Error thrown";
  return "";
}

}  // namespace residue::testing
