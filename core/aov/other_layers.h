// The layers of a render that no AOV role took: a renderer's light passes ("Diffuse Direct"), the colour's alpha,
// cryptomattes, anything else its files hold. The viewer pages through them beside the recognised AOVs (tev's
// layer browsing); a denoise never reads them.
#pragma once

#include <string>
#include <vector>

#include "core/aov/aov_stack.h"
#include "core/aov/channel_naming.h"

namespace residue {

struct OtherLayer {
  std::string name;                  // as the file names it: "ViewLayer.Diffuse Direct", "ViewLayer.Combined.A"
  std::string file;
  std::vector<ChannelRef> channels;  // 1 to 3 of one subimage, in the file's order
};

// The unrecognised channels of the stack's input files (those its AOVs were read from), grouped by layer (a
// channel's name before its last dot) in the files' order (OpenEXR's is alphabetical). A group's alpha channel (A, alpha) is a layer of its
// own, so that it can be looked at alone; other groups of more than three channels are cut into threes. Files
// that cannot be opened again (gone, a stream) contribute nothing.
std::vector<OtherLayer> other_layers(const AovStack& layout);

// A layer's values on the stack's grid (its data window; 0 where the layer's part does not cover it), as stored:
// never decoded from sRGB, never normalised. Error(Input) when the file cannot be read.
Image read_other_layer(const OtherLayer& layer, const AovStack& layout);

}  // namespace residue
