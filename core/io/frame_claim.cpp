#include "core/io/frame_claim.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <vector>

#include <OpenImageIO/imageio.h>

#include "core/util/error.h"

namespace residue::io {
namespace fs = std::filesystem;

namespace {

fs::path claim_path(const fs::path& output) {
  const fs::path folder = output.has_parent_path() ? output.parent_path() : fs::path(".");
  return folder / ("." + output.filename().string() + ".residue-claim");
}

}  // namespace

void FrameClaim::clear_stale(const fs::path& output) {
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(claim_path(output), ec))) return;
  (void)take(output);  // held by no one: taken, and removed as the claim ends; held: left to its owner
}

std::optional<FrameClaim> FrameClaim::take(const fs::path& output) {
  const fs::path path = claim_path(output);
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
  if (fd < 0)
    throw Error(ErrorKind::Output, "cannot claim '" + output.string() + "': cannot create '" + path.string() +
                                       "': " + std::strerror(errno));
  struct flock lock {};
  lock.l_type = F_WRLCK;
  lock.l_whence = SEEK_SET;
  if (::fcntl(fd, F_SETLK, &lock) != 0) {
    ::close(fd);
    return std::nullopt;  // held by another process
  }
  return FrameClaim(path, fd);
}

FrameClaim::FrameClaim(FrameClaim&& other) noexcept : path_(std::move(other.path_)), fd_(other.fd_) {
  other.fd_ = -1;
}

FrameClaim::~FrameClaim() {
  if (fd_ < 0) return;
  ::unlink(path_.c_str());  // before the lock goes: a process that opens the name next makes a new file
  ::close(fd_);
}

ExistingOutput inspect_output(const fs::path& file) {
  if (exr_is_complete(file)) return ExistingOutput::Complete;
  std::error_code ec;
  if (fs::is_regular_file(file, ec) && fs::file_size(file, ec) == 0) return ExistingOutput::Damaged;
  static constexpr char kMagic[4] = {0x76, 0x2f, 0x31, 0x01};
  char head[4] = {};
  std::ifstream in(file, std::ios::binary);
  return in.read(head, 4) && std::memcmp(head, kMagic, 4) == 0 ? ExistingOutput::Damaged : ExistingOutput::Foreign;
}

bool exr_is_complete(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec) || fs::file_size(file, ec) == 0) return false;
  auto in = OIIO::ImageInput::open(file.string());
  if (!in) {
    OIIO::geterror();  // clear it
    return false;
  }
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.deep) return false;
  std::vector<float> row(static_cast<size_t>(spec.width) * static_cast<size_t>(spec.nchannels));
  const int last = spec.y + spec.height - 1;
  const bool ok = in->read_scanlines(0, 0, last, last + 1, 0, 0, spec.nchannels, OIIO::TypeFloat, row.data());
  if (!ok) in->geterror();
  return ok;
}

}  // namespace residue::io
