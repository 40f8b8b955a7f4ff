// What a denoise records in the EXR it writes (io::Provenance, the residue:* attributes), from what ran: one
// function for every writer (the CLI in memory and streamed, the viewer's exports), so a file says the same
// things whichever program wrote it.
#pragma once

#include "core/aov/aov_stack.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/method.h"
#include "core/io/exr_writer.h"
#include "core/io/provenance.h"

namespace residue {

// The run's own facts: backend, post-steps, strength, self-ensemble, and its time when known (stats.seconds > 0;
// a streamed EXR's header is written before the time is).
io::Provenance run_provenance(const DenoiseStats& stats);

// The same with the method that ran: its name and architecture.
io::Provenance provenance_of(const Method& method, const DenoiseStats& stats);

// What a denoised image of `stack` keeps of the render when it is written: its header attributes, data and
// display windows. Every writer of a result (the CLI, the viewer's exports, the Python module) sets them here.
void keep_render_header(io::ExrWriteOptions& exr, const AovStack& stack);

}  // namespace residue
