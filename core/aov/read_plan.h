// How the loader reads one AOV: the file and channels that hold it and what their values mean (ReadPlan), the
// plans that recognition, a file set and an explicit mapping make, and the reading of the pixels with
// OpenImageIO. The loader (aov_loader.cpp) decides which plan each role gets; this file knows files and channels.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>

#include "core/aov/aov_loader.h"
#include "core/aov/aov_stack.h"
#include "core/aov/channel_mapping.h"
#include "core/aov/channel_naming.h"
#include "core/aov/pass_meaning.h"

namespace residue {

// An opened input: its channels and per-subimage windows.
struct OpenedFile {
  std::string path;
  std::string format;  // OpenImageIO's name for it: "openexr", "png", ...
  std::vector<ChannelRef> channels;
  std::vector<OIIO::ImageSpec> specs;
};

// Opens and checks `path` (exists, a sane EXR header, not deep, named for what it is). Error(Input) otherwise.
OpenedFile open_file(const std::filesystem::path& path);
// Its channel names, for messages ("R, G, B, ... (52 in all)").
std::string channel_list(const OpenedFile& f, size_t max_names = 40);
// What an AOV of `role` looks like, for messages.
std::string expected_text(AovRole role);
// Whether a file's values are display-encoded sRGB (a PNG or JPEG as most tools write them).
bool encoded_srgb(const OIIO::ImageSpec& spec);

// What to read for one role.
struct ReadPlan {
  AovRole role = AovRole::Color;
  std::string file;
  std::string layer;
  std::vector<ChannelRef> channels;
  PassMeaning meaning;
  double scale = 1.0;  // the values are read times this
  double depth_background = kDepthBackgroundThreshold;
};

// The plan for a whole single-AOV file: the channels its naming says are `role`, else its first ones.
ReadPlan whole_file_plan(AovRole role, const OpenedFile& f);
ReadPlan plan_from_recognition(const RecognisedAov& r, const std::string& file);
// The plan of an explicit --map binding; Error(Mapping) naming the channel or layer the file lacks.
ReadPlan plan_from_binding(AovRole role, const ChannelBinding& b, const OpenedFile& f);
// Where a plan's AOV comes from.
AovSource describe(const ReadPlan& p);

// Reads every plan that uses `file` into `out[role]`, placing pixels on `grid` (display coordinates).
void read_plans(const OpenedFile& file, const std::vector<const ReadPlan*>& plans, const Rect& grid,
                std::map<AovRole, Aov>& out);

}  // namespace residue
