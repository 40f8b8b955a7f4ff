// residue-cli eval: noisy (and, given --denoised, denoised) against a reference; a table or JSON, and on
// request the per-pixel maps and a metrics file.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>

#include "cli_common.h"
#include "app/common/cli_enum.h"
#include "commands.h"
#include "core/io/atomic_file.h"
#include "core/io/frame_sequence.h"
#include "eval_sequence.h"
#include "core/io/map_writer.h"
#include "core/io/metrics_report.h"
#include "core/metrics/flip.h"
#include "core/metrics/metrics.h"
#include "core/util/error.h"

namespace residue::cli {
namespace {

struct EvalOptions {
  InputOptions input;
  std::string denoised;
  std::string roi;
  double eps = 0.01;
  std::string ssim_space = "tonemapped";
  bool json = false;
  std::string metrics_out;
  std::string maps_dir;
  std::string colormap = "viridis";
  enum class MapFormat { Png, Exr, Both } map_format = MapFormat::Png;
  bool force = false;
  bool flip = true;  // HDR-FLIP beside relMSE and SSIM
  std::string frames;
};

void write_maps(const EvalOptions& o, const std::string& name, const Image& test, const Image& reference,
                const metrics::Options& mopts, const Image* flip_map) {
  const auto colormap = colormap_from_string(o.colormap);
  if (flip_map) {  // FLIP's own presentation: magma over [0, 1], as NVIDIA's tool draws it
    const Image map = mopts.roi ? crop(*flip_map, *mopts.roi) : *flip_map;
    const std::filesystem::path base = std::filesystem::path(o.maps_dir) / (name + "_flip");
    if (o.map_format != EvalOptions::MapFormat::Exr) {
      io::MapPngOptions p;
      p.colormap = Colormap::Magma;
      p.overwrite = o.force;
      p.scale = {false, 0.0, 1.0};
      io::write_map_png(base.string() + ".png", map, p);
    }
    if (o.map_format != EvalOptions::MapFormat::Png) io::write_map_exr(base.string() + ".exr", map, o.force);
  }
  for (metrics::MapKind kind : {metrics::MapKind::AbsoluteError, metrics::MapKind::SquaredError,
                                metrics::MapKind::RelativeSquaredError, metrics::MapKind::Ssim,
                                metrics::MapKind::SignedDifference}) {
    const Image map = metrics::error_map(test, reference, kind, mopts);
    const std::filesystem::path base = std::filesystem::path(o.maps_dir) / (name + "_" + metrics::to_string(kind));
    if (o.map_format != EvalOptions::MapFormat::Exr) {
      io::MapPngOptions p;
      p.colormap = *colormap;
      p.overwrite = o.force;
      // Errors span decades: log scale; SSIM lives in [0, 1]: linear; a signed difference: linear, symmetric about
      // 0, in the diverging colormap whatever --colormap says (blue: darker than the reference, red: brighter).
      if (kind == metrics::MapKind::Ssim) {
        p.scale = {false, 0.0, 1.0};
      } else if (kind == metrics::MapKind::SignedDifference) {
        p.colormap = Colormap::BlueRed;
        p.scale.symmetric = true;
      } else {
        p.scale.log = true;
      }
      io::write_map_png(base.string() + ".png", map, p);
    }
    if (o.map_format != EvalOptions::MapFormat::Png) io::write_map_exr(base.string() + ".exr", map, o.force);
  }
}

int run(const EvalOptions& o) {
  if (!o.metrics_out.empty()) io::refuse_input_as_output(o.metrics_out, o.input.files_named(), "--metrics-out");
  if (o.input.inputs.size() == 1 && io::FramePattern::parse(o.input.inputs.front())) {
    if (!o.maps_dir.empty()) throw Error(ErrorKind::Usage, "--maps-dir is for single images, not sequences");
    if (!o.metrics_out.empty() && std::filesystem::path(o.metrics_out).extension() != ".json")
      throw Error(ErrorKind::Usage, "a sequence's --metrics-out is a .json file");
    return run_eval_sequence({o.input, o.denoised, o.frames, o.eps, o.roi.empty() ? std::nullopt : std::optional(parse_roi(o.roi)),
                              o.json, o.metrics_out, o.force});
  }
  if (!o.frames.empty()) throw Error(ErrorKind::Usage, "--frames is for sequences: give the input as a pattern (shot.####.exr)");
  // The outputs are checked before the (long) metrics; the maps are checked again as each is written.
  if (!o.metrics_out.empty()) io::prepare_metrics_output(o.metrics_out, o.force);
  if (!o.maps_dir.empty() && !std::filesystem::is_directory(o.maps_dir))
    throw Error(ErrorKind::Output, "--maps-dir '" + o.maps_dir + "' is not an existing folder");
  AovStack stack = o.input.load();
  if (!o.json)  // JSON carries them
    for (const std::string& note : stack.notes) std::fprintf(stderr, "note: %s\n", note.c_str());
  if (!stack.reference)
    throw Error(ErrorKind::Usage, "no reference: give --reference FILE (none was found beside '" +
                                      stack.color.source.file + "')");
  metrics::Options mopts;
  mopts.eps = o.eps;
  mopts.ssim_space = o.ssim_space == "linear" ? metrics::SsimSpace::Linear : metrics::SsimSpace::Tonemapped;
  if (!o.roi.empty()) mopts.roi = parse_roi(o.roi);

  io::MetricsReport report;
  report.reference_file = stack.reference->source.file;
  report.width = stack.width();
  report.height = stack.height();
  report.options = mopts;
  report.notes = stack.notes;
  const Image& reference = stack.reference->image;
  // HDR-FLIP is a whole-image map (its filters and exposures see the whole image); a region takes its mean there.
  std::vector<metrics::FlipResult> flips;
  const auto score = [&](const std::string& name, const std::string& file, const Image& test) {
    io::MetricsRow row{name, file, metrics::compare(test, reference, mopts)};
    if (o.flip) {
      flips.push_back(metrics::hdr_flip(test, reference));
      row.hdr_flip = mopts.roi ? metrics::flip_mean(flips.back().map, mopts.roi) : flips.back().mean;
      report.flip = flips.back().exposures;
    }
    report.rows.push_back(std::move(row));
  };
  score("noisy", stack.color.source.file, stack.color.image);

  std::optional<Aov> denoised;
  if (!o.denoised.empty()) {
    LoadOptions lo;
    lo.load_reference = false;
    denoised = load_aov_stack({o.denoised}, lo).color;
    if (denoised->image.width() != stack.width() || denoised->image.height() != stack.height())
      throw Error(ErrorKind::Input, "'" + o.denoised + "' is " + std::to_string(denoised->image.width()) + "x" +
                                        std::to_string(denoised->image.height()) + " but the noisy input is " +
                                        std::to_string(stack.width()) + "x" + std::to_string(stack.height()));
    score("denoised", o.denoised, denoised->image);
  }

  if (!o.maps_dir.empty()) {
    write_maps(o, "noisy", stack.color.image, reference, mopts, o.flip ? &flips[0].map : nullptr);
    if (denoised) write_maps(o, "denoised", denoised->image, reference, mopts, o.flip ? &flips[1].map : nullptr);
  }
  if (!o.metrics_out.empty()) io::write_metrics(o.metrics_out, report, o.force);

  if (o.json) std::cout << io::to_json(report) << "\n";
  else print_metrics_table(report);
  return kOk;
}

}  // namespace

Command add_eval_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("eval", "Score noisy (and denoised) images against a reference: relMSE, MSE, "
                                         "PSNR, SSIM, HDR-FLIP; optionally write per-pixel maps and a metrics file");
  auto o = std::make_shared<EvalOptions>();
  o->input.add_to(*cmd, true);
  cmd->add_option("-d,--denoised", o->denoised, "A denoised image to score as well (for a sequence: a pattern)");
  cmd->add_option("--frames", o->frames, "Sequences (input, -r and --denoised as patterns, shot.####.exr): the frames "
                                         "to score, e.g. 1-24; also reports the flicker (temporal relMSE)");
  cmd->add_option("--roi", o->roi, "Score only the rectangle x,y,w,h (pixels of the data window)");
  cmd->add_option("--eps", o->eps, "relMSE denominator offset: (x-r)^2/(r^2+eps)")
      ->capture_default_str()
      ->check(positive_finite());
  cmd->add_option("--ssim-space", o->ssim_space, "Values SSIM and PSNR are computed on")
      ->capture_default_str()
      ->check(CLI::IsMember({"tonemapped", "linear"}));
  cmd->add_flag("--json", o->json, "Print JSON instead of a table");
  cmd->add_option("--metrics-out", o->metrics_out, "Also write the metrics to FILE (.json or .csv)");
  cmd->add_option("--maps-dir", o->maps_dir,
                  "Write per-pixel maps (abs, se, rse, ssim; diff, signed, in bluered; flip in magma) of each scored "
                  "image into this folder");
  add_on_off(cmd, "--flip", o->flip, "Score HDR-FLIP too (NVIDIA's FLIP over the reference's exposures; about 2 s per "
                                     "megapixel on 2 cores)");
  cmd->add_option("--colormap", o->colormap, "Colormap of PNG maps")
      ->capture_default_str()
      ->check(CLI::IsMember({"viridis", "inferno", "magma", "turbo", "bluered"}));
  using MapFormat = EvalOptions::MapFormat;
  add_enum_option<MapFormat>(cmd, "--map-format", o->map_format,
                             {{"png", MapFormat::Png}, {"exr", MapFormat::Exr}, {"both", MapFormat::Both}},
                             "png (colour-mapped), exr (float values) or both");
  cmd->add_flag("-f,--force", o->force, "Replace output files that already exist");
  return {cmd, [o]() { return run(*o); }};
}

}  // namespace residue::cli
