#include "core/io/provenance.h"

namespace residue::io {

void record(OIIO::ParamValueList& attributes, const Provenance& p) {
  const auto text = [&](const char* name, const std::optional<std::string>& v) {
    if (v) attributes.attribute(name, *v);
  };
  attributes.attribute("residue:version", std::string(RESIDUE_VERSION));
  text("residue:model", p.model);
  text("residue:architecture", p.architecture);
  text("residue:backend", p.backend);
  text("residue:source", p.source);
  text("residue:result", p.result);
  text("residue:written_by", p.written_by);
  if (p.seconds) attributes.attribute("residue:time_s", *p.seconds);
  if (p.energy_correction) attributes.attribute("residue:energy_correction", *p.energy_correction ? 1 : 0);
  if (p.variance_blend) attributes.attribute("residue:variance_blend", *p.variance_blend ? 1 : 0);
  if (p.strength) attributes.attribute("residue:strength", *p.strength);
  if (p.ensemble) attributes.attribute("residue:ensemble", *p.ensemble);
  if (p.temporal_blend) attributes.attribute("residue:temporal_blend", *p.temporal_blend);
  if (p.skip_converged) attributes.attribute("residue:skip_converged", *p.skip_converged);
}

}  // namespace residue::io
