// The tonemap used for SSIM/PSNR and for any display of HDR values that must match them:
// Hable's filmic curve ("Uncharted 2"), normalised so that linear 11.2 maps to 1, then the sRGB OETF.
// This is what Intel Open Image Denoise's comparison tools use, so numbers are comparable.
#pragma once

namespace residue {

// Linear radiance (any value; negatives and NaN give 0) -> display value in [0, 1].
float tonemap_filmic_srgb(float linear);

// The sRGB opto-electronic transfer function on [0, 1] (clamped).
float srgb_oetf(float linear);

}  // namespace residue
