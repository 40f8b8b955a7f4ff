// Writing files without losing what the user owns: every output is written to a temporary file in the
// destination folder and renamed into place. An existing file is never replaced unless `overwrite` is set.
#pragma once

#include <filesystem>
#include <functional>

namespace residue::io {

// Calls write(temp_path) to produce the file, then moves it to `destination`.
// The temporary file is created empty (mode 0666 less the umask) beside the destination, hidden, and ends with the
// destination's extension so that writers that choose the format by name still work:
//   dir/out.exr -> dir/.out.exr.residue-tmp-XXXXXXXX.exr
// It is fsync'ed before the rename. Throws residue::Error(Output) when the destination folder is missing, when
// `destination` exists and !overwrite (checked before calling `write`, and race-free at the rename with
// renameat2(RENAME_NOREPLACE)), or when writing/renaming fails; the temporary file is removed on any failure,
// and an exception thrown by `write` propagates unchanged.
void write_atomically(const std::filesystem::path& destination, bool overwrite,
                      const std::function<void(const std::filesystem::path& temp_path)>& write);

}  // namespace residue::io
