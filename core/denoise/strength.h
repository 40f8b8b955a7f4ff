// Denoising strength: how much of the network's output to keep.
//
//   out' = s out + (1 - s) noisy,   s in [0, 1]: 0 gives the noisy input, 1 the denoised output
//
// The blend is done on linear radiance, the space in which a pixel's value is an estimate of the light: the
// blend's mean over any region is the same blend of the two means, so a strength that keeps some of the noise
// never brightens or darkens the image (a blend of log or tonemapped values would: Jensen's inequality). Where
// the noisy value is not finite the output is kept. It is the last step of a denoise (after the energy
// correction and the variance blend) and cheap, so a viewer can re-blend a kept result instantly.
#pragma once

#include "core/image/image.h"

namespace residue {

// Blends rows [y0, y0 + rows) (image coordinates) of `region` in `out`, whose row 0 is image row `out_y0`,
// towards `noisy`, whose row 0 is image row `noisy_y0` (both the image's width). Error(Usage) for s outside
// [0, 1] or not finite.
void apply_strength(const Image& noisy, int64_t noisy_y0, Image& out, int64_t out_y0, const Rect& region, int64_t y0,
                    int64_t rows, float strength);

// The whole image: `denoised` blended towards `noisy` (same size) with strength s.
Image with_strength(const Image& noisy, const Image& denoised, float strength);

// Error(Usage) unless 0 <= s <= 1.
void check_strength(float strength);

}  // namespace residue
