#include "core/aov/other_layers.h"

#include <algorithm>
#include <map>
#include <set>

#include <OpenImageIO/strutil.h>

#include "core/aov/read_plan.h"
#include "core/util/error.h"

namespace residue {
namespace {

std::string layer_of(const std::string& channel) {
  const auto dot = channel.rfind('.');
  return dot == std::string::npos ? std::string() : channel.substr(0, dot);
}

std::string suffix_of(const std::string& channel) {
  const auto dot = channel.rfind('.');
  return dot == std::string::npos ? channel : channel.substr(dot + 1);
}

bool is_alpha(const std::string& channel) {
  const std::string s = suffix_of(channel);
  return s == "A" || OIIO::Strutil::iequals(s, "alpha");
}

// A channel alone by its name ("layer.A"); the group's channels (but its alpha) by the layer's name when they are
// at most three, else "layer (X,Y,Z)" for each three.
std::string chunk_name(const std::string& layer, const std::vector<ChannelRef>& chunk, bool whole_group,
                       const std::string& file_prefix) {
  std::string name;
  if (chunk.size() == 1) {
    name = chunk.front().name;
  } else {
    name = layer.empty() ? std::string("(root)") : layer;
    if (!whole_group) {
      std::vector<std::string> parts;
      for (const auto& c : chunk) parts.push_back(suffix_of(c.name));
      name += " (" + OIIO::Strutil::join(parts, ",") + ")";
    }
  }
  return file_prefix + name;
}

}  // namespace

std::vector<OtherLayer> other_layers(const AovStack& layout) {
  // The files, colour's first, and the channels the stack took from each.
  std::vector<std::string> files;
  std::map<std::string, std::set<std::pair<int, std::string>>> used;
  for (AovRole role : kAllAovRoles) {
    const Aov* aov = layout.find(role);
    if (!aov || aov->source.file.empty()) continue;
    // A reference in a file of its own is another render, not a layer of this one.
    if (role != AovRole::Reference && std::find(files.begin(), files.end(), aov->source.file) == files.end())
      files.push_back(aov->source.file);
    for (const auto& c : aov->source.channels) used[aov->source.file].insert({aov->source.subimage, c});
  }

  std::vector<OtherLayer> out;
  for (const std::string& file : files) {
    OpenedFile opened;
    try {
      opened = open_file(file);
    } catch (const Error&) {
      continue;
    }
    const std::string prefix =
        files.size() > 1 ? std::filesystem::path(file).filename().string() + ": " : std::string();
    // Groups keyed by (subimage, layer), in order of first appearance.
    std::vector<std::pair<int, std::string>> order;
    std::map<std::pair<int, std::string>, std::vector<ChannelRef>> groups;
    for (const ChannelRef& c : opened.channels) {
      if (used[file].count({c.subimage, c.name})) continue;
      const std::pair<int, std::string> key{c.subimage, layer_of(c.name)};
      if (!groups.count(key)) order.push_back(key);
      groups[key].push_back(c);
    }
    for (const auto& key : order) {
      const auto& group = groups[key];
      std::vector<ChannelRef> alpha, rest;
      for (const auto& c : group) (is_alpha(c.name) && group.size() > 1 ? alpha : rest).push_back(c);
      std::vector<std::vector<ChannelRef>> chunks;
      for (size_t i = 0; i < rest.size(); i += 3)
        chunks.emplace_back(rest.begin() + static_cast<std::ptrdiff_t>(i),
                            rest.begin() + static_cast<std::ptrdiff_t>(std::min(rest.size(), i + 3)));
      for (const auto& a : alpha) chunks.push_back({a});
      for (auto& chunk : chunks) {
        OtherLayer layer;
        layer.name = chunk_name(key.second, chunk, rest.size() <= 3, prefix);
        layer.file = file;
        layer.channels = std::move(chunk);
        out.push_back(std::move(layer));
      }
    }
  }
  return out;
}

Image read_other_layer(const OtherLayer& layer, const AovStack& layout) {
  if (layer.channels.empty() || layer.channels.size() > 3)
    throw Error(ErrorKind::Usage, "layer '" + layer.name + "' has " + std::to_string(layer.channels.size()) +
                                      " channels; 1 to 3 are read");
  const OpenedFile opened = open_file(layer.file);
  // Read as a depth would be: values as stored, never decoded from sRGB (an alpha is not encoded).
  ReadPlan plan;
  plan.role = AovRole::Depth;
  plan.file = layer.file;
  plan.layer = layer.name;
  plan.channels = layer.channels;
  std::map<AovRole, Aov> read;
  read_plans(opened, {&plan}, layout.data_window, read);
  return std::move(read[AovRole::Depth].image);
}

}  // namespace residue
