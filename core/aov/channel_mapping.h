// Explicit channel mappings, for files no convention recognises (or to override what was recognised).
//
// From the command line:   --map albedo=diffuse.R,diffuse.G,diffuse.B
//                          --map normal=/renders/n.exr:N.X,N.Y,N.Z     (another file, its channels)
//                          --map depth=/renders/z.exr                  (another file, all its channels)
//                          --map albedo=diffuse                       (a layer: its R,G,B / X,Y,Z / red,green,blue)
// From a JSON file (--mapping FILE.json):
//   { "layer": "ViewLayer",
//     "color":  {"channels": ["R", "G", "B"]},
//     "normal": {"file": "n.exr", "channels": ["N.X", "N.Y", "N.Z"], "space": "world"},
//     "depth":  {"file": "z.exr", "background": 1e10} }
// Relative files in a JSON mapping are relative to the JSON file's folder.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/aov/aov_stack.h"

namespace residue {

struct ChannelBinding {
  std::string file;                   // empty = the primary input file
  std::vector<std::string> channels;  // names, or one layer name; empty = every channel of `file`
  std::optional<NormalSpace> normal_space;
  std::optional<double> depth_background;  // values >= this are background (in addition to +Inf)
};

struct ChannelMapping {
  std::map<AovRole, ChannelBinding> roles;
  std::string layer_prefix;  // Cycles view layer etc.; empty = automatic

  bool empty() const { return roles.empty() && layer_prefix.empty(); }

  // Parses one "ROLE=[FILE:]CHANNELS" flag; throws Error(Mapping) naming the flag on a bad one.
  void add_flag(const std::string& flag);
  // Reads a JSON mapping file; throws Error(Mapping) naming the file and the bad key.
  static ChannelMapping from_json_file(const std::filesystem::path& path);
  // `other`'s entries replace this one's.
  void merge(const ChannelMapping& other);
};

}  // namespace residue
