#include "eval_sequence.h"

#include <cstdio>
#include <fstream>
#include <iostream>

#include <nlohmann/json.hpp>

#include "core/io/atomic_file.h"
#include "core/io/frame_sequence.h"
#include "core/metrics/metrics.h"
#include "core/metrics/temporal.h"
#include "core/util/error.h"

namespace residue::cli {
namespace {

namespace fs = std::filesystem;
using io::FramePattern;

FramePattern pattern_or_throw(const std::string& text, const char* what) {
  auto p = FramePattern::parse(text);
  if (!p) throw Error(ErrorKind::Usage, std::string(what) + " '" + text + "' must be a frame pattern too (ref.####.exr)");
  return *p;
}

nlohmann::ordered_json scores_json(const metrics::Scores& s) {
  return {{"relmse", s.relmse}, {"ssim", s.ssim}, {"psnr", std::isfinite(s.psnr) ? s.psnr : 0.0}, {"pixels", s.pixels}};
}

}  // namespace

int run_eval_sequence(const EvalSequenceOptions& o) {
  const FramePattern in = pattern_or_throw(o.input.inputs.front(), "input");
  if (o.input.reference.empty())
    throw Error(ErrorKind::Usage, "a sequence needs its references: give -r ref.####.exr");
  const FramePattern ref = pattern_or_throw(o.input.reference, "reference -r");
  const std::optional<FramePattern> den =
      o.denoised.empty() ? std::nullopt : std::optional(pattern_or_throw(o.denoised, "--denoised"));
  const std::vector<int64_t> frames = o.frames.empty() ? io::find_frames(in) : io::parse_frame_spec(o.frames);
  if (frames.size() < 2) throw Error(ErrorKind::Input, "a sequence needs two frames or more; found " + std::to_string(frames.size()));
  if (!o.metrics_out.empty()) io::prepare_output(o.metrics_out, o.force);

  metrics::Options m;
  m.eps = o.eps;
  m.roi = o.roi;
  metrics::TemporalRelMse noisy_t(o.eps, o.roi), denoised_t(o.eps, o.roi);
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  double sums[4] = {0, 0, 0, 0};  // noisy relMSE, SSIM; denoised relMSE, SSIM
  if (!o.json) std::printf("%-8s %12s %9s %12s %9s\n", "frame", "noisy relMSE", "SSIM", "denoised", "SSIM");
  // A frame that cannot be scored (missing, unreadable, another size) is reported and left out, and the
  // sequence goes on, as `denoise` does; the temporal error pairs only frames that follow each other.
  int64_t scored = 0;
  std::vector<std::string> failed;
  for (int64_t f : frames) try {
    LoadOptions load = o.input.load_options();
    load.reference = ref.path(f);
    const AovStack stack = load_aov_stack({in.path(f)}, load);
    const Image& r = stack.reference->image;
    const metrics::Scores noisy = metrics::compare(stack.color.image, r, m);
    nlohmann::ordered_json row{{"frame", f}, {"noisy", scores_json(noisy)}};
    sums[0] += noisy.relmse;
    sums[1] += noisy.ssim;
    std::optional<metrics::Scores> denoised;
    Image d;
    if (den) {
      LoadOptions lo;
      lo.load_reference = false;
      d = load_aov_stack({den->path(f)}, lo).color.image;
      if (d.width() != r.width() || d.height() != r.height())
        throw Error(ErrorKind::Input, "'" + den->path(f).string() + "' is not the size of frame " + std::to_string(f));
    }
    noisy_t.add(stack.color.image, r);
    if (den) {
      denoised = metrics::compare(d, r, m);
      denoised_t.add(d, r);
      row["denoised"] = scores_json(*denoised);
      sums[2] += denoised->relmse;
      sums[3] += denoised->ssim;
    }
    if (!o.json)
      std::printf("%-8lld %12.6f %9.5f %12s %9s\n", static_cast<long long>(f), noisy.relmse, noisy.ssim,
                  denoised ? std::to_string(denoised->relmse).substr(0, 8).c_str() : "-",
                  denoised ? std::to_string(denoised->ssim).substr(0, 7).c_str() : "-");
    rows.push_back(std::move(row));
    ++scored;
  } catch (const Error& e) {
    std::fprintf(stderr, "frame %lld  not scored: %s\n", static_cast<long long>(f), e.what());
    rows.push_back({{"frame", f}, {"error", e.what()}});
    failed.push_back(std::to_string(f));
    noisy_t.gap();
    denoised_t.gap();
  }
  if (scored == 0) throw Error(ErrorKind::Input, "no frame of '" + in.to_string() + "' could be scored (above)");
  const double n = static_cast<double>(scored);
  nlohmann::ordered_json doc{{"input", in.to_string()}, {"reference", ref.to_string()}, {"frames", frames.size()},
                             {"frames_scored", scored}, {"eps", o.eps}};
  doc["mean"] = {{"noisy", {{"relmse", sums[0] / n}, {"ssim", sums[1] / n}}}};
  doc["temporal_relmse"] = {{"noisy", noisy_t.value()}};
  doc["temporal_relmse_symmetric"] = {{"noisy", noisy_t.value_symmetric()}};
  if (den) {
    doc["denoised"] = den->to_string();
    doc["mean"]["denoised"] = {{"relmse", sums[2] / n}, {"ssim", sums[3] / n}};
    doc["temporal_relmse"]["denoised"] = denoised_t.value();
    doc["temporal_relmse_symmetric"]["denoised"] = denoised_t.value_symmetric();
    doc["flicker_ratio"] = denoised_t.value() / noisy_t.value();
  }
  doc["temporal_formula"] = "mean over frame pairs, pixels and RGB of ((x_t - x_{t-1}) - (r_t - r_{t-1}))^2 / (r_t^2 + eps)";
  doc["temporal_symmetric_formula"] =
      "the same divided by (r_t^2 + r_{t-1}^2) / 2 + eps (not dominated by pixels a highlight has just left)";
  doc["per_frame"] = std::move(rows);
  const std::string text = doc.dump(1) + "\n";
  if (o.json) {
    std::cout << text;
  } else {
    std::printf("\nmean     %12.6f %9.5f", sums[0] / n, sums[1] / n);
    if (den) std::printf(" %12.6f %9.5f", sums[2] / n, sums[3] / n);
    std::printf("\ntemporal relMSE (flicker): noisy %.6f", noisy_t.value());
    if (den) std::printf(", denoised %.6f (%.1f %% of the noisy input's)", denoised_t.value(), 100.0 * denoised_t.value() / noisy_t.value());
    std::printf("\ntemporal relMSE, symmetric: noisy %.6f", noisy_t.value_symmetric());
    if (den) std::printf(", denoised %.6f", denoised_t.value_symmetric());
    std::printf("\n  = %s, eps = %g\n", doc["temporal_formula"].get<std::string>().c_str(), o.eps);
    if (!failed.empty())
      std::printf("%zu of %zu frames not scored (above); the means are over the other %lld\n", failed.size(),
                  frames.size(), static_cast<long long>(scored));
  }
  if (!o.metrics_out.empty())
    io::write_atomically(o.metrics_out, o.force, [&](const fs::path& temp) {
      std::ofstream file(temp, std::ios::binary);
      file << text;
      if (!file.flush()) throw Error(ErrorKind::Output, "cannot write '" + o.metrics_out + "'");
    });
  return failed.empty() ? kOk : kInputError;  // as denoise: the run goes on, its exit says a frame failed
}

}  // namespace residue::cli
