// The two ways a network pass runs: over a stack in memory, or streamed from a render's files to an EXR band by
// band (memory within DenoiseOptions::max_memory whatever the image size). Both pull bands from the same
// BandDenoiser, so their outputs are equal.
#pragma once

#include <filesystem>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/engine/network_pass.h"
#include "core/io/exr_writer.h"

namespace residue {

// The pass's output, the stack's size (the image it replaces: colour, or a prefilter's albedo or normal).
Image run_pass(const AovStack& stack, const NetworkPass& pass, const DenoiseOptions& options,
               const TileCallback& on_tile, DenoiseStats& stats, WorkCounter& work);

// The pass from the reader's files to `output`; `exr` as denoise_to_exr takes it (its windows and metadata
// already filled in). Cancelling leaves no file.
DenoiseStats stream_pass(const AovReader& reader, const NetworkPass& pass, const DenoiseOptions& options,
                         const std::filesystem::path& output, io::ExrWriteOptions exr, const TileCallback& on_tile,
                         WorkCounter& work);

}  // namespace residue
