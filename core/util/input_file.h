// The one check every file Residue reads goes through before it is opened: it must be a regular file (or a
// link to one). A device (/dev/zero, /dev/urandom), a FIFO or a socket would make a reader block or spin for
// ever, and a link loop would surface as an internal error.
#pragma once

#include <filesystem>
#include <string>

namespace residue {

// Throws Error(Input) naming `what` ("input", "model file", ...) and the path, saying what it is instead, when
// `path` is missing, a folder (unless `folder_ok`), a device, a FIFO, a socket or a symbolic-link loop.
void check_input_file(const std::filesystem::path& path, const std::string& what, bool folder_ok = false);

}  // namespace residue
