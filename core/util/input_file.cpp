#include "core/util/input_file.h"

#include <cerrno>
#include <system_error>

#include "core/util/error.h"

namespace residue {

void check_input_file(const std::filesystem::path& path, const std::string& what, bool folder_ok) {
  namespace fs = std::filesystem;
  const std::string named = what + " '" + path.string() + "'";
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec && ec.value() == ELOOP)
    throw Error(ErrorKind::Input, named + " is a loop of symbolic links; point it at a file");
  switch (st.type()) {
    case fs::file_type::regular: return;
    case fs::file_type::directory:
      if (folder_ok) return;
      throw Error(ErrorKind::Input, named + " is a folder, not a file");
    case fs::file_type::fifo:
      throw Error(ErrorKind::Input, named + " is a pipe (FIFO): pipes are not supported, as the file is read more "
                                            "than once; write it to a file first");
    case fs::file_type::character:
    case fs::file_type::block:
      throw Error(ErrorKind::Input, named + " is a device, not a file");
    case fs::file_type::socket: throw Error(ErrorKind::Input, named + " is a socket, not a file");
    case fs::file_type::not_found:
      if (fs::is_symlink(fs::symlink_status(path, ec)))
        throw Error(ErrorKind::Input, named + " is a symbolic link to a file that does not exist");
      throw Error(ErrorKind::Input, named + " does not exist");
    default:
      if (ec) throw Error(ErrorKind::Input, "cannot read " + named + ": " + ec.message());
      throw Error(ErrorKind::Input, named + " is not a regular file");
  }
}

}  // namespace residue
