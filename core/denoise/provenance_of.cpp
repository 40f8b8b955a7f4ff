#include "core/denoise/provenance_of.h"

namespace residue {

io::Provenance run_provenance(const DenoiseStats& stats) {
  io::Provenance p;
  p.backend = stats.backend;
  if (stats.seconds > 0) p.seconds = static_cast<float>(stats.seconds);
  p.energy_correction = stats.energy_corrected;
  p.variance_blend = stats.variance_blended;
  p.strength = stats.strength;
  p.ensemble = stats.ensemble;
  if (stats.skip_converged > 0) p.skip_converged = stats.skip_converged;
  return p;
}

io::Provenance provenance_of(const Method& method, const DenoiseStats& stats) {
  io::Provenance p = run_provenance(stats);
  p.model = method.name();
  p.architecture = method.architecture();
  return p;
}

void keep_render_header(io::ExrWriteOptions& exr, const AovStack& stack) {
  exr.metadata = stack.metadata;
  exr.data_window = stack.data_window;
  exr.display_width = stack.display_width;
  exr.display_height = stack.display_height;
}

}  // namespace residue
