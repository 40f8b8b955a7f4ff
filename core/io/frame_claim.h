// Frames of one sequence shared by several processes (a farm task requeued beside the first, two artists on one
// shot): each frame is claimed before it is denoised, and a frame's output is trusted as done only when whole.
#pragma once

#include <filesystem>
#include <optional>

namespace residue::io {

// An exclusive claim on one output frame while it is denoised: a POSIX record lock on a hidden file beside the
// output (".out.0001.exr.residue-claim"). The kernel (or the NFS lock manager) releases it when the process
// ends, however it ends, so a killed run never leaves a frame claimed. The file is removed when the claim ends.
class FrameClaim {
 public:
  // The claim, or nullopt when another process holds it now. Error(Output) when the folder refuses the file.
  static std::optional<FrameClaim> take(const std::filesystem::path& output);
  // Removes the claim file a killed process left beside a frame it had finished (killed between writing the frame
  // and removing its claim), unless a live process holds it. A run that skips a finished frame calls this, so no
  // hidden file outlives the sequence's next run.
  static void clear_stale(const std::filesystem::path& output);
  FrameClaim(FrameClaim&& other) noexcept;
  FrameClaim& operator=(FrameClaim&&) = delete;
  FrameClaim(const FrameClaim&) = delete;
  ~FrameClaim();

 private:
  FrameClaim(std::filesystem::path path, int fd) : path_(std::move(path)), fd_(fd) {}
  std::filesystem::path path_;
  int fd_ = -1;
};

// Whether an output frame is a whole EXR: its header opens and its last scanline reads (a file cut short by a
// full disk or a killed copy, or left at 0 bytes, is not).
bool exr_is_complete(const std::filesystem::path& file);

// What an existing output frame is: a whole EXR; damaged (empty, or an EXR cut short: a frame to redo); or
// foreign (another kind of file, which a resumed run leaves alone: it may be the user's).
enum class ExistingOutput { Complete, Damaged, Foreign };
ExistingOutput inspect_output(const std::filesystem::path& file);

}  // namespace residue::io
