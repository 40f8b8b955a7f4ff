// Loading an AOV stack from EXR files with OpenImageIO: one multilayer/multipart file, a single-AOV file set,
// or an explicit mapping. See channel_naming.h and file_sets.h for what is recognised.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "core/aov/aov_stack.h"
#include "core/aov/channel_mapping.h"
#include "core/aov/channel_naming.h"

namespace residue {

struct LoadOptions {
  ChannelMapping mapping;                          // explicit bindings; override what is recognised
  std::optional<std::filesystem::path> reference;  // a reference colour in another file
  std::optional<NormalSpace> normal_space;         // override what the convention says
  bool load_reference = true;                      // attach a reference found by convention
};

// Reads an AOV stack lazily: the constructor opens the inputs, recognises and checks the channels (all errors
// of load_aov_stack come from here) and reads no pixels; read() then loads any rectangle, so a huge render can
// be processed band by band in bounded memory.
class AovReader {
 public:
  AovReader(const std::vector<std::filesystem::path>& inputs, const LoadOptions& options = {});
  ~AovReader();
  AovReader(const AovReader&) = delete;
  AovReader& operator=(const AovReader&) = delete;

  // Everything but the pixels: convention, sources, windows, metadata, camera, notes. AOV images are empty.
  const AovStack& layout() const;
  // The AOVs of `rect` (pixels of the data window), normalised as load_aov_stack does; the result's images are
  // rect-sized (its data_window still describes the whole image).
  // `roles`: read only these (the others stay as in layout(), without pixels); empty: every AOV.
  AovStack read(const Rect& rect, const std::vector<AovRole>& roles = {}) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Loads the stack. `inputs`: one file, one folder, or several single-AOV files.
// Throws residue::Error(Input | Mapping) that names the file, the channels found and the channels expected.
AovStack load_aov_stack(const std::vector<std::filesystem::path>& inputs, const LoadOptions& options = {});

// Depth values at or above this are "no hit" (Cycles Depth.Z writes 1e10 there).
inline constexpr double kDepthBackgroundThreshold = 1e9;

// The loader's last step, for AOVs that come from elsewhere too (a stream): flips a normal's z when its
// convention says so, sets depth at or above `depth_background` to 0, counts non-finite values into `aov`.
// Returns how many depth pixels were background.
int64_t normalise_aov(AovRole role, bool flip_normal_z, double depth_background, Aov& aov);

// The channels of every subimage of `file`, for `info` and for error messages.
struct FileChannels {
  std::string file;
  std::vector<ChannelRef> channels;
  int64_t width = 0, height = 0;
};
FileChannels list_channels(const std::filesystem::path& file);

}  // namespace residue
