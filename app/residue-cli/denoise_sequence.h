// Frame sequences: `residue-cli denoise shot.####.exr -o out.####.exr [--frames 1001-1100] [--skip-existing]`.
//
// Each frame is denoised as a single render is (denoise_frame.h), with the models loaded and their backends
// planned once for the whole sequence. Every output is checked before the first frame runs; an existing output
// is an error unless --skip-existing (resume: the frame is skipped) or --force (replaced). A frame that fails
// is reported and the others go on unless --fail-fast; no frame is ever left partly written (writes are
// atomic). A summary (frames done, skipped, failed, time, per-frame metrics when references exist) is printed,
// and written as JSON with --summary. Exit code: 0 when every frame was denoised or skipped, else that of the
// first failure (3 input, 4 output, ...), 130/143 when interrupted.
#pragma once

#include "denoise_frame.h"

namespace residue::cli {

// The input names a frame pattern (shot.####.exr, shot.%04d.exr).
bool is_sequence(const DenoiseCliOptions& options);
int run_sequence(const DenoiseCliOptions& options);

}  // namespace residue::cli
