// Writing files without losing what the user owns: every output is written to a temporary file in the
// destination folder and renamed into place. An existing file is never replaced unless `overwrite` is set.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace residue::io {

// Checks, before any work is done, that `destination` can be written: a file name (not a folder, not ending in
// "/"), in an existing folder the user may write to, and absent unless `overwrite`. Throws Error(Output) naming
// the path and what is wrong; an existing output that is not a regular file (a device, a FIFO, a socket, or a
// link to one) is refused even with `overwrite`. Then removes the temporary files that earlier runs writing `destination` on this
// machine left when they were killed (their process is gone) and returns their paths, so the caller can say so.
std::vector<std::filesystem::path> prepare_output(const std::filesystem::path& destination, bool overwrite);

// Refuses an output whose name does not end in one of `extensions` (".json"; case-insensitive): a summary
// named like a frame would replace the frame. Throws Error(Usage) naming `option`, the path and what it needs.
void require_extension(const std::filesystem::path& destination, const std::vector<std::string>& extensions,
                       const std::string& option);

// Refuses an output that is one of the files the run reads (the same file by inode, or the same path once
// made absolute), even with --force: replacing it would lose the user's data. Throws Error(Output) naming both.
// `lost` names what would be lost ("the render"; default "it").
void refuse_input_as_output(const std::filesystem::path& destination,
                            const std::vector<std::filesystem::path>& inputs, const std::string& option,
                            const std::string& lost = "it");

// Calls write(temp_path) to produce the file, then moves it to `destination` (prepare_output() runs first).
// The temporary file is created empty (mode 0666 less the umask) beside the destination, hidden, names the
// machine and process writing it, and ends with the destination's extension so that writers that choose the
// format by name still work:
//   dir/out.exr -> dir/.out.exr.residue-tmp-HOST-PID-XXXXXX.exr
// It is fsync'ed before the rename. Throws residue::Error(Output) when the destination folder is missing, when
// `destination` exists and !overwrite (checked before calling `write`, and race-free at the rename with
// renameat2(RENAME_NOREPLACE)), or when writing/renaming fails; the temporary file is removed on any failure,
// and an exception thrown by `write` propagates unchanged.
void write_atomically(const std::filesystem::path& destination, bool overwrite,
                      const std::function<void(const std::filesystem::path& temp_path)>& write);

// Removes the temporary files of every write in progress, for a process about to exit on a signal without
// unwinding. Thread-safe (not async-signal-safe: call it from a thread, not a handler).
void remove_temp_files_in_progress();

}  // namespace residue::io
