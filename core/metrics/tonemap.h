// The tonemap used for SSIM/PSNR and for any display of HDR values that must match them:
// Hable's filmic curve ("Uncharted 2"), normalised so that linear 11.2 maps to 1, then the sRGB OETF.
// This is what Intel Open Image Denoise's comparison tools use, so numbers are comparable.
//
// Exactly, for a linear value x (no exposure scale):
//   f(x) = (x (A x + C B) + D E) / (x (A x + B) + D F) - E / F,
//          A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30
//   t    = clamp(f(x) / f(11.2), 0, 1)               (f is increasing on x >= 0, f(0) = 0)
//   out  = srgb_oetf(t) = 12.92 t                     if t < 0.0031308
//                         1.055 t^(1/2.4) - 0.055     otherwise, clamped to [0, 1]
// x <= 0, -Inf and NaN give 0; x >= 11.2 and +Inf give 1 (so huge values never overflow).
// Both functions are evaluated in double; the float versions round the double result once.
#pragma once

namespace residue {

// Linear radiance (any value; negatives and NaN give 0) -> display value in [0, 1].
float tonemap_filmic_srgb(float linear);

// The same curve in double precision; the metrics (SSIM and PSNR on tonemapped values) use this one so that
// their numbers match a float64 reference implementation (NumPy / scikit-image) to ~1e-15.
double tonemap_filmic_srgb_f64(double linear);

// The sRGB opto-electronic transfer function on [0, 1] (clamped; NaN gives 0).
float srgb_oetf(float linear);

}  // namespace residue
