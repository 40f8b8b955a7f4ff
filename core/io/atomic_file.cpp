#include "core/io/atomic_file.h"

#include <fcntl.h>
#include <sys/statvfs.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <climits>
#include <csignal>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <random>
#include <set>
#include <string>

#include <OpenImageIO/strutil.h>

#include "core/util/error.h"

// The temporary file sits beside the destination, hidden, and keeps the destination's extension at the end so
// that writers that pick the format from the name (OpenImageIO) write the right format:
//   folder/out.exr  ->  folder/.out.exr.residue-tmp-HOST-PID-XXXXXX.exr
// It is created with O_EXCL and mode 0666 (the umask applies), so the final file gets the usual permissions.
// HOST and PID say who writes it: a later run on the same output removes it when that process is gone (killed
// with SIGKILL, or the machine lost power); files of other machines (a shared folder on a farm) are left alone.

namespace residue::io {
namespace fs = std::filesystem;

namespace {

std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

[[noreturn]] void fail(const std::string& message) { throw Error(ErrorKind::Output, message); }

std::string errno_text(int err) { return std::strerror(err); }

std::string exists_message(const fs::path& destination) {
  return "output " + quoted(destination) + " exists; pass --force to replace it";
}

std::string host_name() {
  char name[HOST_NAME_MAX + 1] = {};
  if (::gethostname(name, sizeof(name) - 1) != 0 || name[0] == '\0') return "localhost";
  std::string s = name;
  for (char& c : s)
    if (c == '/') c = '_';
  return s;
}

// ".NAME.residue-tmp-": NAME cut short so that the whole temporary name (HOST-PID-XXXXXX and the extension
// follow) fits in NAME_MAX even when the destination's own name nearly fills it.
std::string temp_prefix(const fs::path& destination) {
  static const std::string host = host_name();
  constexpr size_t kFixed = 1 + 13 + 1 + 10 + 1 + 6;  // ".", ".residue-tmp-", "-", a pid, "-", XXXXXX
  const std::string name = destination.filename().string();
  const size_t room = NAME_MAX - std::min<size_t>(NAME_MAX, kFixed + host.size() + destination.extension().string().size());
  return "." + name.substr(0, std::min(name.size(), room)) + ".residue-tmp-";
}

// What an existing path is, when it is not something an output may replace ("" when it may).
std::string not_replaceable(const fs::path& destination) {
  std::error_code ec;
  const fs::file_status link = fs::symlink_status(destination, ec);
  const fs::file_status target = fs::status(destination, ec);  // what a link points to
  for (const fs::file_status& st : {link, target}) {
    switch (st.type()) {
      case fs::file_type::character: return "a character device";
      case fs::file_type::block: return "a block device";
      case fs::file_type::fifo: return "a FIFO (named pipe)";
      case fs::file_type::socket: return "a socket";
      default: break;
    }
  }
  return "";
}

// Bytes the user may still write in `folder`'s file system (-1 when unknown).
int64_t free_bytes(const fs::path& folder) {
  struct statvfs st {};
  if (::statvfs(folder.c_str(), &st) != 0) return -1;
  return static_cast<int64_t>(st.f_bavail) * static_cast<int64_t>(st.f_frsize);
}


// The temporary files of writes in progress in this process (removed by remove_temp_files_in_progress()).
std::mutex g_temps_mutex;
std::set<std::string> g_temps;

// Creates an empty, unique temporary file in `folder`; returns its path.
fs::path create_temp_file(const fs::path& folder, const fs::path& destination) {
  static constexpr char kAlphabet[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789";
  thread_local std::mt19937_64 rng{std::random_device{}() ^
                                   static_cast<uint64_t>(reinterpret_cast<uintptr_t>(&rng))};
  std::uniform_int_distribution<size_t> pick(0, sizeof(kAlphabet) - 2);
  const std::string extension = destination.extension().string();
  const std::string owner = host_name() + "-" + std::to_string(::getpid()) + "-";
  int last_error = 0;
  for (int attempt = 0; attempt < 100; ++attempt) {
    std::string unique(6, 'x');
    for (char& c : unique) c = kAlphabet[pick(rng)];
    fs::path temp = folder / (temp_prefix(destination) + owner + unique + extension);
    std::lock_guard lock(g_temps_mutex);  // registered before it exists, so a signal's clean-up sees it
    g_temps.insert(temp.string());
    int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd >= 0) {
      ::close(fd);
      return temp;
    }
    g_temps.erase(temp.string());
    last_error = errno;
    if (last_error != EEXIST) break;
  }
  fail("cannot create a temporary file in " + quoted(folder) + " for " + quoted(destination) + ": " +
       errno_text(last_error));
}

// Flushes a file's (or folder's) contents to disk.
void sync_path(const fs::path& path, bool directory, bool required, const fs::path& destination) {
  int fd = ::open(path.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
  if (fd < 0 || ::fsync(fd) != 0) {
    int err = errno;
    if (fd >= 0) ::close(fd);
    if (required) fail("cannot flush " + quoted(destination) + " to disk: " + errno_text(err));
    return;
  }
  ::close(fd);
}

int rename_noreplace(const fs::path& from, const fs::path& to) {
#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 28))
  return ::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), RENAME_NOREPLACE);
#else
  return static_cast<int>(::syscall(SYS_renameat2, AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), 1u));
#endif
}

// Moves `temp` to `destination`; without `overwrite`, fails if the destination exists at that moment.
void move_into_place(const fs::path& temp, const fs::path& destination, bool overwrite) {
  if (overwrite) {
    if (std::rename(temp.c_str(), destination.c_str()) != 0)
      fail("cannot move the written file to " + quoted(destination) + ": " + errno_text(errno));
    return;
  }
  if (rename_noreplace(temp, destination) == 0) return;
  int err = errno;
  if (err == EINVAL || err == ENOSYS || err == ENOTSUP) {
    // The file system (or kernel) lacks RENAME_NOREPLACE: link() also refuses to replace, atomically.
    if (::link(temp.c_str(), destination.c_str()) == 0) {
      ::unlink(temp.c_str());
      return;
    }
    err = errno;
  }
  if (err == EEXIST) fail(exists_message(destination));
  fail("cannot move the written file to " + quoted(destination) + ": " + errno_text(err));
}

void forget_temp(const fs::path& path) {
  std::lock_guard lock(g_temps_mutex);
  g_temps.erase(path.string());
}

// Removes the temporary file unless released.
class TempGuard {
 public:
  explicit TempGuard(fs::path path) : path_(std::move(path)) {}
  ~TempGuard() {
    if (path_.empty()) return;
    ::unlink(path_.c_str());
    forget_temp(path_);
  }
  TempGuard(const TempGuard&) = delete;
  TempGuard& operator=(const TempGuard&) = delete;
  void release() {
    forget_temp(path_);
    path_.clear();
  }

 private:
  fs::path path_;
};

fs::path folder_of(const fs::path& destination) {
  return destination.has_parent_path() ? destination.parent_path() : fs::path(".");
}

// A temporary file of `destination` whose writer, on this machine, no longer runs.
bool is_abandoned_temp(const std::string& name, const fs::path& destination, const std::string& host) {
  const std::string prefix = temp_prefix(destination), extension = destination.extension().string();
  if (name.size() <= prefix.size() + extension.size() || name.compare(0, prefix.size(), prefix) != 0 ||
      name.compare(name.size() - extension.size(), extension.size(), extension) != 0)
    return false;
  // HOST-PID-XXXXXX, the host possibly holding dashes itself: split from the right.
  const std::string owner = name.substr(prefix.size(), name.size() - prefix.size() - extension.size());
  const auto random_dash = owner.rfind('-');
  if (random_dash == std::string::npos || random_dash == 0) return false;
  const auto pid_dash = owner.rfind('-', random_dash - 1);
  if (pid_dash == std::string::npos || owner.substr(0, pid_dash) != host) return false;
  const std::string pid_text = owner.substr(pid_dash + 1, random_dash - pid_dash - 1);
  if (pid_text.empty() || pid_text.size() > 9 || pid_text.find_first_not_of("0123456789") != std::string::npos)
    return false;
  const auto pid = static_cast<pid_t>(std::stol(pid_text));
  return pid != ::getpid() && ::kill(pid, 0) != 0 && errno == ESRCH;
}

}  // namespace

std::vector<fs::path> prepare_output(const fs::path& destination, bool overwrite) {
  const std::string text = destination.string();
  if (destination.filename().empty() || destination.filename() == "." || destination.filename() == ".." ||
      (!text.empty() && text.back() == '/'))
    fail("output " + quoted(destination) + " is not a file name");
  const fs::path folder = folder_of(destination);
  std::error_code ec;
  if (!fs::is_directory(folder, ec))
    fail("cannot write " + quoted(destination) + ": the folder " + quoted(folder) + " does not exist");
  if (fs::is_directory(destination, ec)) fail("output " + quoted(destination) + " is a folder, not a file");
  if (const std::string what = not_replaceable(destination); !what.empty())
    fail("output " + quoted(destination) + " is " + what + ": Residue writes regular files only (even with --force)");
  if (::access(folder.c_str(), W_OK | X_OK) != 0)
    fail("cannot write " + quoted(destination) + ": the folder " + quoted(folder) + " is not writable (" +
         errno_text(errno) + ")");
  // A dangling symbolic link counts as existing.
  if (!overwrite && fs::exists(fs::symlink_status(destination, ec))) fail(exists_message(destination));

  std::vector<fs::path> removed;
  const std::string host = host_name();
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (is_abandoned_temp(name, destination, host) && ::unlink(it->path().c_str()) == 0) removed.push_back(it->path());
  }
  return removed;
}

void require_extension(const fs::path& destination, const std::vector<std::string>& extensions,
                       const std::string& option) {
  for (const std::string& e : extensions)
    if (OIIO::Strutil::iequals(destination.extension().string(), e) && destination.stem() != "") return;
  std::string list;
  for (const std::string& e : extensions) list += (list.empty() ? "" : " or ") + e;
  throw Error(ErrorKind::Usage, option + " " + quoted(destination) + ": give it a name ending in " + list);
}

void refuse_input_as_output(const fs::path& destination, const std::vector<fs::path>& inputs,
                            const std::string& option, const std::string& lost) {
  std::error_code ec;
  const fs::path absolute = fs::weakly_canonical(fs::absolute(destination, ec), ec);
  for (const fs::path& input : inputs) {
    std::error_code e1, e2;
    const bool same = fs::equivalent(destination, input, e1) ||
                      (!absolute.empty() && absolute == fs::weakly_canonical(fs::absolute(input, e2), e2));
    if (same)
      throw Error(ErrorKind::Output, option + " " + quoted(destination) + " is the input " + quoted(input) +
                                         ", which this run reads: writing there would lose " + lost + " (even with --force); "
                                         "choose another name");
  }
}

void remove_temp_files_in_progress() {
  std::lock_guard lock(g_temps_mutex);
  for (const std::string& path : g_temps) ::unlink(path.c_str());
  g_temps.clear();
}

void write_atomically(const fs::path& destination, bool overwrite,
                      const std::function<void(const fs::path& temp_path)>& write) {
  prepare_output(destination, overwrite);
  const fs::path folder = folder_of(destination);
  std::error_code ec;
  const fs::path temp = create_temp_file(folder, destination);
  TempGuard guard(temp);
  // A full disk surfaces as whatever the writer makes of a short write, naming the hidden temporary file: say
  // what happened, naming the destination.
  const auto no_space = [&] {
    const int64_t left = free_bytes(folder);
    return left >= 0 && left < (int64_t{1} << 16);
  };
  try {
    write(temp);
    if (!fs::is_regular_file(temp, ec))
      fail("cannot write " + quoted(destination) + ": the temporary file " + quoted(temp) + " disappeared");
    sync_path(temp, false, true, destination);
  } catch (const Error&) {
    if (no_space()) fail("cannot write " + quoted(destination) + ": no space left on device (" + quoted(folder) + ")");
    throw;
  }
  move_into_place(temp, destination, overwrite);
  guard.release();
  sync_path(folder, true, false, destination);  // make the rename durable; not fatal if unsupported
}

}  // namespace residue::io
