// Recognising AOVs from channel names, by the naming conventions of the renderers people use.
//
// Pure functions of the channel list (no I/O), so every convention is testable on names alone.
// The conventions themselves (which renderer names what) are in core/aov/conventions.h.
#pragma once

#include <string>
#include <vector>

#include "core/aov/aov_stack.h"
#include "core/aov/pass_meaning.h"

namespace residue {

// One channel of an input file.
struct ChannelRef {
  int subimage = 0;
  int index = 0;           // within its subimage
  std::string name;        // as stored
  std::string pixel_type;  // "half", "float", ...
};

struct RecognisedAov {
  AovRole role = AovRole::Color;
  std::string layer;                 // the pass name it matched, e.g. "Denoising Normal"
  std::vector<ChannelRef> channels;  // in the order the stack wants them (R,G,B / X,Y,Z / Z)
  PassMeaning meaning;               // the matching rule's
};

struct Recognition {
  std::string convention;            // empty when no colour was found
  std::vector<RecognisedAov> aovs;   // at most one per role
  std::vector<std::string> notes;    // fallbacks taken, ambiguities resolved
  const RecognisedAov* find(AovRole role) const;
};

// Finds the AOVs in `channels` (all subimages of one file). `layer_prefix` picks one view layer when a file
// holds several (e.g. Cycles "ViewLayer"); empty = the first prefix that has a beauty pass.
Recognition recognise_channels(const std::vector<ChannelRef>& channels, const std::string& layer_prefix = "");

// The layers (or view-layer prefixes) of a file: the first part of each dotted channel name ("ViewLayer" of
// "ViewLayer.Combined.R", "Beta" of "Beta.R"), in order of first appearance, as stored.
std::vector<std::string> layer_names(const std::vector<ChannelRef>& channels);

// Finds `count` channels for a layer: e.g. ("diffuse", 3) -> diffuse.red/green/blue. Used for explicit
// mappings that name a layer rather than channels. Empty when not found.
std::vector<ChannelRef> find_layer_channels(const std::vector<ChannelRef>& channels, const std::string& layer,
                                            int count);

}  // namespace residue
