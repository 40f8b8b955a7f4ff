// An independent, float64, untiled re-implementation of Intel Open Image Denoise 2.4's "RT" filter, for tests.
//
// Written from OIDN's behaviour as specified (autoexposure, transfer functions, input/output processing, the UNet
// and UNetLarge graphs) and nothing else in Residue: it shares no code with core/nn or core/denoise, so that
// Residue's own engine can be checked against it. Plain nested loops in double; slow (about 16 GFLOP for a
// 256 x 256 image with the base UNet), meant for small images.
#pragma once

#include <cmath>

#include "core/image/image.h"
#include "core/nn/tza.h"

namespace residue::testing {

// OIDN 2.4's RT filter in float64, untiled. color: W x H x 3 HDR linear; albedo/normal optional (nullptr), same
// size. `weights`: a TZA file read with nn::read_tza. Returns W x H x 3.
// Filtering an auxiliary image alone (OIDN's prefiltering) passes an empty color (or nullptr to the overload
// below) and exactly one of albedo (needs hdr = false) or normal. Throws std::invalid_argument on a combination OIDN does not accept, on sizes that
// differ, and on weights that do not fit the inputs.
Image naive_oidn_filter(const nn::TzaFile& weights, const Image& color, const Image* albedo, const Image* normal,
                        bool hdr = true, double input_scale = NAN /* NAN: autoexposure when hdr, else 1 */);

// The same with the colour optional (nullptr), for filtering an albedo or normal image alone.
Image naive_oidn_filter(const nn::TzaFile& weights, const Image* color, const Image* albedo, const Image* normal,
                        bool hdr, double input_scale = NAN);

// OIDN's autoexposure: 0.18 / (geometric mean of the mean luminance of bins of at most 16 x 16 pixels).
double oidn_autoexposure(const Image& color);  // exposed for tests

// OIDN's perceptually uniform (PU) transfer curve, unnormalised.
double pu_forward(double y);
double pu_inverse(double x);

}  // namespace residue::testing
