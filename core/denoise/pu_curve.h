// The PU transfer curve Open Image Denoise runs its HDR networks in (a three-piece fit of the perceptually uniform
// encoding of Aydin et al. 2008), in one place: core's OIDN filter applies it (oidn_filter.cpp) and the trainer
// measures a loss in it (app/residue-train/training_loss.cpp, issue 16 lever 1).
//   pu(y) = A y                      for y <= Y0
//         = B y^C + D                for Y0 < y <= Y1
//         = E log(y + F) + G         above Y1
// X0 and X1 are pu(Y0) and pu(Y1), the inverse's breakpoints. OIDN normalises it so that the largest half value,
// kHdrMax, maps to 1.
#pragma once

namespace residue::pu_curve {

constexpr float A = 1.41283765e+03f, B = 1.64593172e+00f, C = 4.31384981e-01f, D = -2.94139609e-03f;
constexpr float E = 1.92653254e-01f, F = 6.26026094e-03f, G = 9.98620152e-01f;
constexpr float Y0 = 1.57945760e-06f, Y1 = 3.22087631e-02f, X0 = 2.23151711e-03f, X1 = 3.70974749e-01f;
constexpr float kHdrMax = 65504.0f;

}  // namespace residue::pu_curve
