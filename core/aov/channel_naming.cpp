#include "core/aov/channel_naming.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <map>
#include <tuple>

#include "core/aov/conventions.h"

namespace residue {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// A channel name split as prefix.layer.component, e.g. "ViewLayer.Denoising Albedo.R" ->
// {"viewlayer", "denoising albedo", "r"}; "R" -> {"", "", "r"}; "Z" -> {"", "", "z"}; ".R" (V-Ray) -> {"", "", "r"}.
struct SplitName {
  std::string prefix;
  std::string layer;
  std::string component;
};

SplitName split(const std::string& stored) {
  std::string name = stored;
  while (!name.empty() && name.front() == '.') name.erase(0, 1);  // V-Ray writes root channels as ".R"
  SplitName s;
  const auto last = name.rfind('.');
  if (last == std::string::npos) {
    s.component = lower(name);
    return s;
  }
  s.component = lower(name.substr(last + 1));
  std::string layer_path = name.substr(0, last);
  const auto mid = layer_path.rfind('.');
  if (mid == std::string::npos) {
    s.layer = lower(layer_path);
  } else {
    s.prefix = lower(layer_path.substr(0, mid));
    s.layer = lower(layer_path.substr(mid + 1));
  }
  return s;
}

const std::vector<std::vector<std::string>> kTriplets = {
    {"r", "g", "b"}, {"x", "y", "z"}, {"red", "green", "blue"}, {"u", "v", "w"}};
const std::vector<std::string> kSingles = {"z", "y", "v", "r", "l", "a"};

// Channels indexed by (prefix, layer) -> component -> channel.
using LayerIndex = std::map<std::pair<std::string, std::string>, std::map<std::string, ChannelRef>>;

LayerIndex index_channels(const std::vector<ChannelRef>& channels) {
  LayerIndex idx;
  for (const auto& c : channels) {
    SplitName s = split(c.name);
    idx[{s.prefix, s.layer}].emplace(s.component, c);  // first occurrence wins
  }
  return idx;
}

// The channels of `layer` under `prefix` for a role needing `count` channels; empty when absent.
std::vector<ChannelRef> take(const LayerIndex& idx, const std::string& prefix, const std::string& layer,
                             int count) {
  // A bare root channel used as a one-channel layer: e.g. Arnold's "Z" is (prefix "", layer "", component "z").
  if (count == 1 && prefix.empty()) {
    auto root = idx.find({"", ""});
    if (root != idx.end()) {
      auto it = root->second.find(layer);
      if (it != root->second.end()) return {it->second};
    }
  }
  auto it = idx.find({prefix, layer});
  if (it == idx.end()) return {};
  const auto& comps = it->second;
  if (count == 3) {
    for (const auto& t : kTriplets) {
      if (comps.count(t[0]) && comps.count(t[1]) && comps.count(t[2]))
        return {comps.at(t[0]), comps.at(t[1]), comps.at(t[2])};
    }
    return {};
  }
  if (count == 4) {
    for (const auto& q : {std::array<const char*, 4>{"x", "y", "z", "w"}, std::array<const char*, 4>{"r", "g", "b", "a"}})
      if (comps.count(q[0]) && comps.count(q[1]) && comps.count(q[2]) && comps.count(q[3]))
        return {comps.at(q[0]), comps.at(q[1]), comps.at(q[2]), comps.at(q[3])};
    return {};
  }
  for (const auto& s : kSingles)
    if (comps.count(s)) return {comps.at(s)};
  if (comps.size() == 1) return {comps.begin()->second};
  return {};
}

// The layer part of a stored channel name, in its original case ("ViewLayer.Denoising Albedo.R" ->
// "ViewLayer.Denoising Albedo"); root channels are shown as "(root)".
std::string stored_layer(const std::string& channel, bool root) {
  const auto last = channel.rfind('.');
  if (root || last == std::string::npos || last == 0) return "(root)";
  return channel.substr(0, last);
}

// Said when a pass a rule looks for is there but lacks channels (e.g. albedo.R and albedo.G without albedo.B),
// so that a render silently falling back to a colour-only model says why.
std::string incomplete_pass_note(AovRole role, const std::map<std::string, ChannelRef>& comps, int count) {
  std::vector<const ChannelRef*> refs;
  for (const auto& entry : comps) refs.push_back(&entry.second);
  std::sort(refs.begin(), refs.end(), [](const ChannelRef* a, const ChannelRef* b) {
    return std::tie(a->subimage, a->index) < std::tie(b->subimage, b->index);
  });
  std::string found;
  for (const ChannelRef* ref : refs) found += (found.empty() ? "" : ", ") + ref->name;
  return std::string("the ") + to_string(role) + " pass has only " + found + " (expected " + std::to_string(count) +
         " channels: R,G,B or X,Y,Z); it is not used";
}

bool has_root_rgb(const LayerIndex& idx) {
  auto it = idx.find({"", ""});
  return it != idx.end() && it->second.count("r") && it->second.count("g") && it->second.count("b");
}

}  // namespace

const RecognisedAov* Recognition::find(AovRole role) const {
  for (const auto& a : aovs)
    if (a.role == role) return &a;
  return nullptr;
}

std::vector<ChannelRef> find_layer_channels(const std::vector<ChannelRef>& channels, const std::string& layer,
                                            int count) {
  const LayerIndex idx = index_channels(channels);
  SplitName s = split(layer + ".x");  // reuse the splitter for "prefix.layer"
  return take(idx, s.prefix, s.layer, count);
}

std::vector<std::string> layer_names(const std::vector<ChannelRef>& channels) {
  std::vector<std::string> names;
  for (const auto& c : channels) {
    const auto dot = c.name.find('.');
    if (dot == std::string::npos || dot == 0) continue;
    const std::string name = c.name.substr(0, dot);
    if (std::find(names.begin(), names.end(), name) == names.end()) names.push_back(name);
  }
  return names;
}

Recognition recognise_channels(const std::vector<ChannelRef>& channels, const std::string& layer_prefix) {
  const LayerIndex idx = index_channels(channels);
  // The prefixes present (Cycles view layers), in order of first appearance.
  std::vector<std::string> prefixes;
  for (const auto& c : channels) {
    std::string p = split(c.name).prefix;
    if (std::find(prefixes.begin(), prefixes.end(), p) == prefixes.end()) prefixes.push_back(p);
  }
  const std::string wanted_prefix = lower(layer_prefix);

  for (const LayeredConvention& conv : layered_conventions()) {
    if (conv.needs_root_rgb && !has_root_rgb(idx)) continue;
    for (const std::string& prefix : prefixes) {
      if (!wanted_prefix.empty() && prefix != wanted_prefix) continue;
      // A one-letter layer may also be a root channel (Arnold's "Z").
      const auto present = [&](const std::string& layer) {
        return idx.count({prefix, layer}) || (prefix.empty() && layer.size() == 1 && idx.count({"", ""}) &&
                                              idx.at({"", ""}).count(layer));
      };
      const bool signed_here =
          conv.signatures.empty() ||
          std::any_of(conv.signatures.begin(), conv.signatures.end(),
                      [&](const auto& set) { return std::all_of(set.begin(), set.end(), present); });
      if (!signed_here) continue;

      Recognition rec;
      rec.convention = conv.name;
      for (const PassRule& rule : conv.rules) {
        if (rec.find(rule.role)) continue;
        const int count = expected_channels(rule.role);
        for (const std::string& layer : rule.layers) {
          // Root-layer beauty is never under a prefix; but a layer named like the prefix stands for it
          // ("Beta.R" beside "Beta.albedo.R": a render's layer whose passes are prefixed by its name).
          const std::string& p = layer.empty() ? std::string() : prefix;
          std::vector<ChannelRef> found;
          if (layer.empty() && !prefix.empty()) found = take(idx, "", prefix, count);
          if (found.empty()) found = take(idx, p, layer, count);
          if (found.empty() && rule.role == AovRole::Variance) found = take(idx, p, layer, 1);
          if (found.empty()) {
            if (auto it = idx.find({p, layer}); count == 3 && !layer.empty() && it != idx.end())
              rec.notes.push_back(incomplete_pass_note(rule.role, it->second, count));
            continue;
          }
          RecognisedAov aov;
          aov.role = rule.role;
          aov.layer = stored_layer(found.front().name, layer.empty());
          aov.channels = std::move(found);
          aov.meaning = rule.meaning;
          rec.aovs.push_back(std::move(aov));
          if (!rule.note.empty()) rec.notes.push_back(rule.note);
          break;
        }
      }
      if (!rec.find(AovRole::Color)) continue;
      if (prefixes.size() > 1 && wanted_prefix.empty() && !prefix.empty())
        rec.notes.push_back("several layer prefixes in the file; using \"" + prefix +
                            "\" (choose another with --layer)");
      return rec;
    }
  }
  return {};
}

}  // namespace residue
