#include "core/io/atomic_file.h"

#include <fcntl.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>

#include "core/util/error.h"

// The temporary file sits beside the destination, hidden, and keeps the destination's extension at the end so
// that writers that pick the format from the name (OpenImageIO) write the right format:
//   folder/out.exr  ->  folder/.out.exr.residue-tmp-XXXXXXXX.exr
// It is created with O_EXCL and mode 0666 (the umask applies), so the final file gets the usual permissions.

namespace residue::io {
namespace fs = std::filesystem;

namespace {

std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

[[noreturn]] void fail(const std::string& message) { throw Error(ErrorKind::Output, message); }

std::string errno_text(int err) { return std::strerror(err); }

std::string exists_message(const fs::path& destination) {
  return "output " + quoted(destination) + " exists; pass --force to replace it";
}

// Creates an empty, unique temporary file in `folder`; returns its path.
fs::path create_temp_file(const fs::path& folder, const fs::path& destination) {
  static constexpr char kAlphabet[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789";
  thread_local std::mt19937_64 rng{std::random_device{}() ^
                                   static_cast<uint64_t>(reinterpret_cast<uintptr_t>(&rng))};
  std::uniform_int_distribution<size_t> pick(0, sizeof(kAlphabet) - 2);
  const std::string name = destination.filename().string();
  const std::string extension = destination.extension().string();
  int last_error = 0;
  for (int attempt = 0; attempt < 100; ++attempt) {
    std::string unique(8, 'x');
    for (char& c : unique) c = kAlphabet[pick(rng)];
    fs::path temp = folder / ("." + name + ".residue-tmp-" + unique + extension);
    int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd >= 0) {
      ::close(fd);
      return temp;
    }
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

// Removes the temporary file unless released.
class TempGuard {
 public:
  explicit TempGuard(fs::path path) : path_(std::move(path)) {}
  ~TempGuard() {
    if (!path_.empty()) ::unlink(path_.c_str());
  }
  TempGuard(const TempGuard&) = delete;
  TempGuard& operator=(const TempGuard&) = delete;
  void release() { path_.clear(); }

 private:
  fs::path path_;
};

}  // namespace

void write_atomically(const fs::path& destination, bool overwrite,
                      const std::function<void(const fs::path& temp_path)>& write) {
  if (destination.filename().empty() || destination.filename() == "." || destination.filename() == "..")
    fail("output " + quoted(destination) + " is not a file name");
  const fs::path folder = destination.has_parent_path() ? destination.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(folder, ec))
    fail("cannot write " + quoted(destination) + ": the folder " + quoted(folder) + " does not exist");
  // Fail fast, before any work; a dangling symbolic link counts as existing.
  if (!overwrite && fs::exists(fs::symlink_status(destination, ec))) fail(exists_message(destination));

  const fs::path temp = create_temp_file(folder, destination);
  TempGuard guard(temp);
  write(temp);
  if (!fs::is_regular_file(temp, ec))
    fail("cannot write " + quoted(destination) + ": the temporary file " + quoted(temp) + " disappeared");
  sync_path(temp, false, true, destination);
  move_into_place(temp, destination, overwrite);
  guard.release();
  sync_path(folder, true, false, destination);  // make the rename durable; not fatal if unsupported
}

}  // namespace residue::io
