// residue-cli denoise: an AOV stack in, a denoised EXR out (atomic, never replacing without --force), with a
// progress bar on a terminal, plain lines otherwise, and metrics when a reference is known; or a frame sequence
// (shot.####.exr) in, one EXR per frame out (denoise_sequence.h).
#include <cstdio>
#include <memory>

#include "cli_common.h"
#include "commands.h"
#include "core/io/frame_sequence.h"
#include "core/denoise/method_registry.h"
#include "core/nn/model_card.h"
#include "core/util/error.h"
#include "denoise_frame.h"
#include "denoise_sequence.h"

namespace residue::cli {
namespace {

int run(const DenoiseCliOptions& o) {
  if (o.temporal && is_model_free_method(o.model))
    throw Error(ErrorKind::Usage, "--temporal runs a temporal network; the " + o.model + " filter denoises frames one by one");
  if (o.ensemble > 1 && is_model_free_method(o.model))
    throw Error(ErrorKind::Usage, "--ensemble " + std::to_string(o.ensemble) + ": the self-ensemble averages a network "
                                  "under flips; the " + o.model + " filter has none (leave --ensemble out)");
  if (o.temporal_blend && !is_sequence(o))
    throw Error(ErrorKind::Usage, "--temporal-blend averages a frame with its neighbours: give the input as a pattern "
                                  "(shot.####.exr or shot.%04d.exr)");
  if (is_sequence(o)) return run_sequence(o);
  if (!o.frames.empty() || o.skip_existing || !o.summary.empty())
    throw Error(ErrorKind::Usage, "--frames, --skip-existing and --summary are for frame sequences: give the input as "
                                  "a pattern (shot.####.exr or shot.%04d.exr)");
  const InterruptScope interrupt;
  FrameContext context{o, interrupt};
  const std::vector<std::filesystem::path> inputs(o.input.inputs.begin(), o.input.inputs.end());
  FrameResult r;
  try {
    r = denoise_frame(context, inputs, o.input.load_options(), o.output);
  } catch (const Cancelled&) {
    std::fprintf(stderr, "\ndenoise: interrupted; nothing was written\n");
    return interrupt.interrupted() ? interrupt.exit_code() : 130;
  }
  if (interrupt.interrupted()) {  // the signal came while the file was being written: it is complete
    std::fprintf(stderr, "\ndenoise: interrupted after %s was written (complete; kept)\n", display_path(o.output).c_str());
    return interrupt.exit_code();
  }
  const DenoiseStats& stats = r.stats;
  std::printf("wrote      %s%s\n", display_path(o.output).c_str(), r.streamed ? " (streamed band by band)" : "");
  std::printf("model      %s (%s)%s%s\n", r.model.c_str(), r.architecture.c_str(),
              stats.ensemble > 1 ? (", self-ensemble x" + std::to_string(stats.ensemble)).c_str() : "",
              stats.strength < 1.0f ? (", strength " + std::to_string(stats.strength).substr(0, 4)).c_str() : "");
  std::printf("backend    %s\n", stats.backend.c_str());
  std::printf("time       %.3f s, %.3f s per megapixel; %lld tiles of %lld px, %lld skipped (empty)\n", stats.seconds,
              stats.seconds / r.megapixels, static_cast<long long>(stats.tiles), static_cast<long long>(stats.tile_size),
              static_cast<long long>(stats.skipped));
  if (stats.skip_converged > 0)
    std::printf("converged  %.1f %% of the pixels kept as rendered (relative variance <= %g); the network on %lld "
                "rectangle%s, %.1f %% of the image with %s halo\n",
                100.0 * static_cast<double>(stats.converged_pixels) / (r.megapixels * 1e6),
                static_cast<double>(stats.skip_converged), static_cast<long long>(stats.regions), stats.regions == 1 ? "" : "s",
                100.0 * static_cast<double>(stats.network_pixels) / (r.megapixels * 1e6), stats.regions == 1 ? "its" : "their");
  if (r.read_s >= 0) std::printf("files      read %.3f s, written %.3f s\n", r.read_s, r.write_s);
  if (stats.clamped_to_half > 0)
    std::fprintf(stderr, "warning: %lld output values exceed the half-float range and were written as +-65504; "
                         "--float keeps them\n", static_cast<long long>(stats.clamped_to_half));
  if (stats.guarded_values > 0)
    std::printf("guard      %lld output values clamped where the network overshot its input's range\n",
                static_cast<long long>(stats.guarded_values));
  if (r.metrics) {
    std::printf("\n");
    print_metrics_table(*r.metrics);
  }
  return kOk;
}

}  // namespace

Command add_denoise_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("denoise", "Denoise a render (or a frame sequence) with a residual-network model and write EXRs");
  auto o = std::make_shared<DenoiseCliOptions>();
  o->input.add_to(*cmd, true);
  cmd->add_option("-o,--output", o->output, "The denoised EXR to write (for a sequence: a pattern, out.####.exr)")->required();
  cmd->add_option("-m,--model", o->model,
                  "A model name (residue-cli models lists them), a .safetensors file, \"bilateral\" (the baseline "
                  "filter), or \"oidn\" / \"oidn-cleanaux\" (Open Image Denoise's networks, for comparison)")
      ->capture_default_str();
  cmd->add_flag("--temporal", o->temporal,
                "Sequences: denoise each frame with its neighbours, warped to it along the motion vectors (the "
                "renderer's motion AOV, e.g. Cycles' Vector pass): less flicker. Runs " +
                    std::string(nn::kDefaultTemporalModel) + " unless -m names another temporal model");
  auto* blend = cmd->add_flag("--temporal-blend", o->temporal_blend,
                "Sequences: average each frame's denoised colour with frames t-1 and t+1's, brought to it along the "
                "motion vectors where they show the same surface and their colours agree (less flicker, for any "
                "model; each frame is still denoised once)");
  cmd->add_option("--blend-tolerance", o->blend_tolerance,
                  "--temporal-blend: the relative colour difference |a - b| / (a + b) beyond which a neighbour's "
                  "colour is left out (a highlight or shadow the motion vectors do not follow)")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 10.0))
      ->needs(blend);
  cmd->add_option("--backend", o->backend, "Inference backend (default: the faster here: eigen for fp32 on CPUs with AVX-512, else onednn)")
      ->check(CLI::IsMember(nn::available_backends()));
  cmd->add_option("--precision", o->precision, "fp32, or bf16 (oneDNN; AMX where present)")
      ->capture_default_str()
      ->check(CLI::IsMember(nn::precision_names()));
  cmd->add_option("--tile", o->tile, "Tile edge in pixels, without the halo (default: the largest within --max-memory)")
      ->check(CLI::Range(int64_t{16}, int64_t{1} << 20));
  cmd->add_option("--threads", o->threads, "Threads (default: every core)")->check(CLI::Range(1, 1024));
  cmd->add_option("--roi", o->roi, "Denoise only the rectangle x,y,w,h; elsewhere the noisy colour is kept");
  cmd->add_option("--max-memory", o->max_memory_mib, "Memory for tiles and the output, in MiB")
      ->capture_default_str()
      ->check(CLI::Range(size_t{1}, size_t{1} << 24));
  cmd->add_flag("--no-skip", o->no_skip, "Run the network on empty (all-black) tiles too");
  cmd->add_flag("--no-energy-correction", o->no_energy_correction,
                "Keep the network's output as it is (by default it is rescaled to the noisy input's local mean, "
                "which removes the darkening of very noisy dark regions)");
  cmd->add_flag("--no-variance-blend", o->no_variance_blend,
                "Keep the network's output where the input is already clean (by default, when the render has a "
                "variance AOV, pixels with a small relative variance keep more of the noisy input)");
  cmd->add_option("--strength", o->strength,
                  "Denoising strength: 1 keeps the denoised output, 0 the noisy input, between a linear blend of the "
                  "two (which keeps the image's brightness)")
      ->capture_default_str()
      ->check(CLI::Range(0.0f, 1.0f));
  cmd->add_option("--skip-converged", o->skip_converged,
                  "Keep the noisy colour where the render has converged (its relative variance, from a variance AOV "
                  "or the two halves of a render, is at most RV: its relMSE as it is) and run the network only on "
                  "rectangles covering the rest, faded into it (off by default; docs/PERFORMANCE.md has the curve)")
      ->type_name("RV")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--ensemble", o->ensemble,
                  "Self-ensemble: run the network under 1, 2, 4 or 8 flips and transposes of the image and average "
                  "(N times the work for a lower error; default: the model's, 1 for most)")
      ->check(CLI::IsMember({1, 2, 4, 8}));
  cmd->add_flag("--float", o->float_output, "Write 32-bit float channels (default: half)");
  cmd->add_option("--compression", o->compression, "EXR compression (zip, piz, dwaa, none, ...)")->capture_default_str();
  auto* force = cmd->add_flag("-f,--force", o->force, "Replace the output if it exists");
  cmd->add_option("--frames", o->frames,
                  "Sequences: the frames to denoise, e.g. 1001-1100, 1001-1100x2 or 1,5,7-20:2 (default: every frame "
                  "whose input exists)")
      ->check(non_empty("frames such as 1001-1100"));
  cmd->add_flag("--skip-existing", o->skip_existing,
                "Sequences: skip frames whose output exists (resume an interrupted run; the default under Slurm)")
      ->excludes(force);
  cmd->add_flag("--fail-fast", o->fail_fast, "Sequences: stop at the first frame that fails (default: go on)");
  cmd->add_option("--summary", o->summary,
                  "Sequences: write a JSON summary (each frame's status, time, metrics when a reference exists)");
  return {cmd, [o]() { return run(*o); }};
}

}  // namespace residue::cli
