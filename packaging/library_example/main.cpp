// Denoise one render with Residue's library: load its AOVs, run the default model, score it against the reference
// when there is one, and write the result as an EXR.  denoise_one RENDER OUTPUT.exr [MODEL]
#include <cstdio>
#include <exception>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/method_registry.h"
#include "core/features/features.h"
#include "core/io/exr_writer.h"
#include "core/metrics/metrics.h"
#include "core/nn/model_registry.h"

int main(int argc, char** argv) {
  if (argc < 3) return std::fprintf(stderr, "usage: denoise_one RENDER OUTPUT.exr [MODEL]\n"), 2;
  try {
    const residue::AovStack stack = residue::load_aov_stack({argv[1]});  // colour, albedo, normal, depth, ...
    residue::nn::ModelRegistry models;                                     // each model file read once
    const auto method = residue::resolve_method(argc > 3 ? argv[3] : residue::nn::kDefaultModel,
                                                residue::feature_set_for(stack), models);
    residue::DenoiseStats stats;
    const residue::Image out = residue::denoise(stack, *method, {}, {}, &stats);
    residue::io::ExrWriteOptions exr;
    exr.pixel_type = residue::io::PixelType::Half;
    residue::io::write_exr(argv[2], out, exr);  // refuses to replace a file unless exr.overwrite
    std::printf("%s: %s in %.2f s\n", argv[2], method->name().c_str(), stats.seconds);
    if (stack.reference)
      std::printf("relMSE %.6g (noisy %.6g)\n", residue::metrics::compare(out, stack.reference->image).relmse,
                  residue::metrics::compare(stack.color.image, stack.reference->image).relmse);
    return 0;
  } catch (const std::exception& e) {  // residue::Error names the file, the channel or the option
    std::fprintf(stderr, "denoise_one: %s\n", e.what());
    return 1;
  }
}
