// Writing files without losing what the user owns: every output is written to a temporary file in the
// destination folder and renamed into place. An existing file is never replaced unless `overwrite` is set.
#pragma once

#include <filesystem>
#include <functional>

namespace residue::io {

// Calls write(temp_path) to produce the file, then moves it to `destination`.
// Throws residue::Error(Output) when `destination` exists and !overwrite (checked before and, race-free,
// at the rename), or when writing/renaming fails; the temporary file is removed on any failure.
void write_atomically(const std::filesystem::path& destination, bool overwrite,
                      const std::function<void(const std::filesystem::path& temp_path)>& write);

}  // namespace residue::io
