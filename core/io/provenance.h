// Provenance: what a denoised EXR records about how it was made, as residue:* header attributes. One owner for
// the names and types, used by residue-cli, the streamed denoise in core and the viewer's exports, so that a file
// says the same things whichever wrote it. Only the fields that are set are written.
#pragma once

#include <OpenImageIO/paramlist.h>
#include <optional>
#include <string>

namespace residue::io {

struct Provenance {
  std::optional<std::string> model;         // residue:model, the model (or method) that made the pixels
  std::optional<std::string> architecture;  // residue:architecture, "8/32 full", "OIDN UNet (rt_hdr_alb_nrm)"
  std::optional<std::string> backend;       // residue:backend
  std::optional<std::string> source;        // residue:source, the noisy render it came from
  std::optional<std::string> result;        // residue:result, the viewer's name for it ("small fp32")
  std::optional<std::string> written_by;    // residue:written_by, "residue-cli", "residue viewer"
  std::optional<float> seconds;             // residue:time_s, the denoise's wall time
  std::optional<bool> energy_correction;    // residue:energy_correction (0/1)
  std::optional<bool> variance_blend;       // residue:variance_blend (0/1)
  std::optional<float> strength;            // residue:strength
  std::optional<int> ensemble;              // residue:ensemble, the self-ensemble's members (1, 2, 4, 8)
  std::optional<float> temporal_blend;      // residue:temporal_blend, the tolerance of the blend with frames t-1, t+1
  std::optional<float> skip_converged;      // residue:skip_converged, the relative variance kept as converged
};

// Adds the set fields, and residue:version always, to `attributes` (replacing attributes of the same name).
void record(OIIO::ParamValueList& attributes, const Provenance& p);

}  // namespace residue::io
