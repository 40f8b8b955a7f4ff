// Intel Open Image Denoise's published networks (resources/models/oidn/*.tza, Apache-2.0) as Residue graphs:
// its UNet (enc_conv0 ... dec_conv0: 5 levels, ReLU after every conv, the last included) and UNetLarge
// (enc_conv1a/1b ... dec_conv1c), told apart as OIDN itself does, by the presence of enc_conv1b. Every conv
// is 3x3 with bias; each decoder level convolves the upsampled features concatenated with the encoder's
// pooled features of that level (the first level: with the network's input). The graph is what OIDN 2.4
// runs; the input and output transforms around it live in core/denoise/oidn_filter.h.
#pragma once

#include <string>

#include "core/nn/graph.h"
#include "core/nn/tza.h"

namespace residue::nn {

// Throws Error(Input) naming `where` and the tensor when a tensor is missing, has the wrong shape, or when the
// first conv's input channels differ from `input_channels` (3 per image: colour, albedo, normal as given).
Graph oidn_graph(const TzaFile& weights, int input_channels, const std::string& where);

// True for the large variant (UNetLarge).
bool oidn_is_large(const TzaFile& weights);
// "UNet" or "UNetLarge", for a graph oidn_graph built.
const char* oidn_network_name(const Graph& graph);

}  // namespace residue::nn
