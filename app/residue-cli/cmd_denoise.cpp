// residue-cli denoise: an AOV stack in, a denoised EXR out (atomic, never replacing without --force), with a
// progress bar on a terminal, plain lines otherwise, and metrics when a reference is known.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <memory>

#include "cli_common.h"
#include "commands.h"
#include "core/denoise/bilateral.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/strength.h"
#include "core/features/features.h"
#include "core/io/exr_writer.h"
#include "core/metrics/metrics.h"
#include "core/util/error.h"
#include "interrupt.h"

namespace residue::cli {
namespace {

struct DenoiseCliOptions {
  InputOptions input;
  std::string output;
  std::string model;
  std::string backend;
  std::string precision = "fp32";
  int64_t tile = 0;
  int threads = 0;
  std::string roi;
  size_t max_memory_mib = 4096;
  bool no_skip = false;
  bool no_energy_correction = false;
  bool no_variance_blend = false;
  bool float_output = false;
  float strength = 1.0f;
  std::string compression = "zip";
  bool force = false;
};

// Draws "[#####.....] 12/40 tiles" on a terminal, or one line per ~10% otherwise.
class ProgressReporter {
 public:
  ProgressReporter() : tty_(isatty(STDERR_FILENO) != 0) {}
  void tile(const TileEvent& e) {
    if (tty_) {
      const int width = 30;
      const int filled = static_cast<int>(width * e.done / std::max<int64_t>(1, e.total));
      std::fprintf(stderr, "\r[%s%s] %lld/%lld tiles", std::string(static_cast<size_t>(filled), '#').c_str(),
                   std::string(static_cast<size_t>(width - filled), '.').c_str(), static_cast<long long>(e.done),
                   static_cast<long long>(e.total));
      if (e.done == e.total) std::fprintf(stderr, "\n");
    } else if (e.done == e.total || e.done * 10 / e.total != (e.done - 1) * 10 / e.total) {
      std::fprintf(stderr, "denoise: %lld/%lld tiles\n", static_cast<long long>(e.done), static_cast<long long>(e.total));
    }
  }

 private:
  bool tty_;
};

// Bytes an in-memory denoise holds for the whole image: every AOV as float, plus the output.
size_t whole_image_bytes(const AovStack& layout) {
  return static_cast<size_t>((layout.channel_count() + 3) * layout.data_window.area()) * sizeof(float);
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The files a render is read from (every AOV's, the reference's).
std::vector<std::string> input_files(const AovStack& layout) {
  std::vector<std::string> files = {layout.color.source.file};
  for (const std::optional<Aov>* a : {&layout.albedo, &layout.normal, &layout.depth, &layout.variance, &layout.reference})
    if (a->has_value()) files.push_back((*a)->source.file);
  return files;
}

// Every check on the output, before any work: the output may not be one of the files read (even with --force:
// the render's AOVs would be lost), then prepare_exr_output()'s (name, compression, folder, overwrite).
void check_output(const std::string& output, const AovStack& layout, const io::ExrWriteOptions& w) {
  std::error_code ec;
  for (const std::string& f : input_files(layout))
    if (std::filesystem::equivalent(output, f, ec))
      throw Error(ErrorKind::Output, "output '" + output + "' is the input '" + f +
                                         "': writing the denoised colour there would lose the render; choose another name");
  for (const auto& removed : io::prepare_exr_output(output, w))
    std::fprintf(stderr, "note: removed '%s', a partial output left by an earlier run that was killed\n",
                 removed.c_str());
}

int run(const DenoiseCliOptions& o) {
  const std::vector<std::filesystem::path> inputs(o.input.inputs.begin(), o.input.inputs.end());
  const AovReader reader(inputs, o.input.load_options());
  const AovStack& layout = reader.layout();
  for (const std::string& note : layout.notes) std::fprintf(stderr, "note: %s\n", note.c_str());
  const Rect whole{0, 0, layout.data_window.width, layout.data_window.height};
  DenoiseOptions d;
  d.backend = o.backend;
  d.precision = o.precision == "bf16" ? nn::Precision::BF16 : nn::Precision::FP32;
  d.tile = o.tile;
  d.threads = o.threads;
  d.max_memory = o.max_memory_mib << 20;
  d.skip_empty_tiles = !o.no_skip;
  d.energy_correction = !o.no_energy_correction;
  d.variance_blend = !o.no_variance_blend;
  d.strength = o.strength;
  if (!o.roi.empty()) d.roi = parse_roi(o.roi);

  io::ExrWriteOptions w;
  w.pixel_type = o.float_output ? io::PixelType::Float : io::PixelType::Half;
  w.compression = o.compression;
  w.metadata = layout.metadata;
  w.data_window = layout.data_window;
  w.display_width = layout.display_width;
  w.display_height = layout.display_height;
  w.overwrite = o.force;
  w.residue_attributes.attribute("residue:version", RESIDUE_VERSION);
  w.residue_attributes.attribute("residue:source", layout.color.source.file);
  check_output(o.output, layout, w);

  ProgressReporter progress;
  const InterruptScope interrupt;
  d.cancel = &interrupt.token();
  auto on_tile = [&](const TileEvent& e, const Image&) {
    progress.tile(e);
    // Another process may create the output meanwhile: say so now rather than after the work.
    std::error_code ec;
    if (!o.force && std::filesystem::exists(std::filesystem::symlink_status(o.output, ec)))
      throw Error(ErrorKind::Output, "output '" + o.output + "' was created by another program during the denoise; "
                                     "nothing was replaced (pass --force to replace it)");
    return !interrupt.interrupted();
  };
  DenoiseStats stats;
  double read_s = -1, write_s = -1;  // in-memory runs: reading the AOVs, writing the EXR
  std::string model_name = o.model, architecture = "cross-bilateral filter";
  // Renders that fit in --max-memory are denoised in memory; larger ones band by band from and to the files
  // (then the header cannot carry the time, which is known only at the end).
  const bool streamed = o.model != "bilateral" && whole_image_bytes(layout) > d.max_memory;
  try {
    if (o.model == "bilateral") {  // the baseline, also a fast preview
      const AovStack stack = reader.read(whole);
      const auto t0 = std::chrono::steady_clock::now();
      const Image out = with_strength(stack.color.image, cross_bilateral(stack, {}, d.roi), d.strength);
      stats.strength = d.strength;
      throw_if_cancelled(d.cancel);
      stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      stats.backend = "cross-bilateral (core)";
      stats.tiles = 1;
      stats.tile_size = std::max(stack.width(), stack.height());
      w.residue_attributes.attribute("residue:model", model_name);
      w.residue_attributes.attribute("residue:architecture", architecture);
      w.residue_attributes.attribute("residue:backend", stats.backend);
      w.residue_attributes.attribute("residue:time_s", static_cast<float>(stats.seconds));
      w.residue_attributes.attribute("residue:strength", stats.strength);
      stats.clamped_to_half = io::write_exr(o.output, out, w).clamped_to_half;
    } else {
      // A model name picks the variant trained for the AOVs this render has (NAME, NAME-albedo-normal, NAME-color).
      const nn::Model model = nn::load_model(nn::find_model_for(o.model, feature_set_for(layout)));
      model_name = model.name;
      architecture = model.architecture();
      w.residue_attributes.attribute("residue:model", model_name);
      w.residue_attributes.attribute("residue:architecture", architecture);
      if (streamed) {  // the header, written first, says which post-steps run (core decides, as below)
        stats = denoise_to_exr(reader, model, d, o.output, w, on_tile);
      } else {
        auto t0 = std::chrono::steady_clock::now();
        const AovStack stack = reader.read(whole);
        read_s = seconds_since(t0);
        const Image out = denoise(stack, model, d, on_tile, &stats);
        throw_if_cancelled(d.cancel);
        w.residue_attributes.attribute("residue:backend", stats.backend);
        w.residue_attributes.attribute("residue:time_s", static_cast<float>(stats.seconds));
        w.residue_attributes.attribute("residue:energy_correction", stats.energy_corrected ? 1 : 0);
        w.residue_attributes.attribute("residue:variance_blend", stats.variance_blended ? 1 : 0);
        w.residue_attributes.attribute("residue:strength", stats.strength);
        t0 = std::chrono::steady_clock::now();
        stats.clamped_to_half = io::write_exr(o.output, out, w).clamped_to_half;
        write_s = seconds_since(t0);
      }
    }
  } catch (const Cancelled&) {
    std::fprintf(stderr, "\ndenoise: interrupted; nothing was written\n");
    return interrupt.interrupted() ? interrupt.exit_code() : 130;
  }
  if (interrupt.interrupted()) {  // the signal came while the file was being written: it is complete
    std::fprintf(stderr, "\ndenoise: interrupted after %s was written (complete; kept)\n", display_path(o.output).c_str());
    return interrupt.exit_code();
  }

  const double megapixels = static_cast<double>(d.roi ? d.roi->area() : whole.area()) / 1e6;
  std::printf("wrote      %s%s\n", display_path(o.output).c_str(), streamed ? " (streamed band by band)" : "");
  std::printf("model      %s (%s)%s\n", model_name.c_str(), architecture.c_str(),
              stats.strength < 1.0f ? (", strength " + std::to_string(stats.strength).substr(0, 4)).c_str() : "");
  std::printf("backend    %s\n", stats.backend.c_str());
  std::printf("time       %.3f s, %.3f s per megapixel; %lld tiles of %lld px, %lld skipped (empty)\n", stats.seconds,
              stats.seconds / megapixels, static_cast<long long>(stats.tiles), static_cast<long long>(stats.tile_size),
              static_cast<long long>(stats.skipped));
  if (read_s >= 0) std::printf("files      read %.3f s, written %.3f s\n", read_s, write_s);
  if (stats.clamped_to_half > 0)
    std::fprintf(stderr, "warning: %lld output values exceed the half-float range and were written as +-65504; "
                         "--float keeps them\n", static_cast<long long>(stats.clamped_to_half));
  if (stats.guarded_values > 0)
    std::printf("guard      %lld output values clamped where the network overshot its input's range\n",
                static_cast<long long>(stats.guarded_values));
  if (layout.reference) {
    // Scored from the file written, as the user will see it.
    const AovStack stack = reader.read(whole);
    LoadOptions lo;
    lo.load_reference = false;
    const Image denoised = load_aov_stack({o.output}, lo).color.image;
    metrics::Options m;
    m.roi = d.roi;
    io::MetricsReport report{layout.reference->source.file, whole.width, whole.height, m, {}};
    report.rows.push_back({"noisy", layout.color.source.file, metrics::compare(stack.color.image, stack.reference->image, m)});
    report.rows.push_back({"denoised", o.output, metrics::compare(denoised, stack.reference->image, m)});
    std::printf("\n");
    print_metrics_table(report);
  }
  return kOk;
}

}  // namespace

Command add_denoise_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("denoise", "Denoise a render with a residual-network model and write an EXR");
  auto o = std::make_shared<DenoiseCliOptions>();
  o->input.add_to(*cmd, true);
  cmd->add_option("-o,--output", o->output, "The denoised EXR to write")->required();
  cmd->add_option("-m,--model", o->model, "A model name (see resources/models), a .safetensors file, \"bilateral\" (the baseline filter), or \"oidn\" / \"oidn-cleanaux\" (Open Image Denoise's networks, for comparison)")->required();
  cmd->add_option("--backend", o->backend, "Inference backend (default: the fastest available)")
      ->check(CLI::IsMember(nn::available_backends()));
  cmd->add_option("--precision", o->precision, "fp32, or bf16 (oneDNN; AMX where present)")
      ->capture_default_str()
      ->check(CLI::IsMember({"fp32", "bf16"}));
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
  cmd->add_flag("--float", o->float_output, "Write 32-bit float channels (default: half)");
  cmd->add_option("--compression", o->compression, "EXR compression (zip, piz, dwaa, none, ...)")->capture_default_str();
  cmd->add_flag("-f,--force", o->force, "Replace the output if it exists");
  return {cmd, [o]() { return run(*o); }};
}

}  // namespace residue::cli
