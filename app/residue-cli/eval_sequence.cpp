#include "eval_sequence.h"

#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>

#include <nlohmann/json.hpp>

#include "core/io/atomic_file.h"
#include "core/io/frame_sequence.h"
#include "core/metrics/metrics.h"
#include "core/metrics/temporal.h"
#include "core/temporal/frame_window.h"
#include "core/temporal/warped_error.h"
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

// Pixels of frame t that a neighbouring frame (t-1 or t+1, where the sequence has it) does not show: the
// surface was hidden or off screen there (core/temporal/frame_window.h's mask). Where a temporal denoiser has
// only frame t's samples, and where it would ghost if it trusted a neighbour. Empty when the frame has no motion
// AOV or no neighbour. `previous`: frame t-1 when the loop has it already (scored just before), else null and it
// is read here.
Image disocclusion_mask(const AovStack& frame, const FramePattern& in, int64_t f, const LoadOptions& load,
                        const AovStack* previous) {
  if (!frame.motion) return {};
  LoadOptions lo = load;
  lo.load_reference = false;
  lo.reference.reset();
  std::map<int, AovStack> read;
  std::map<int, const AovStack*> near;
  if (previous) near[-1] = previous;
  for (int d : {-1, 1})
    if (!near.count(d) && fs::exists(in.path(f + d)))
      near[d] = &read.emplace(d, load_aov_stack({in.path(f + d)}, lo)).first->second;
  if (near.empty()) return {};
  AovStack t = frame;
  attach_neighbours(t, 1, [&](int d) -> const AovStack* {
    const auto it = near.find(d);
    return it == near.end() ? nullptr : it->second;
  });
  Image mask(frame.width(), frame.height(), 1);
  for (const WarpedNeighbour& n : t.neighbours)
    for (int64_t i = 0; i < static_cast<int64_t>(mask.size()); ++i)
      if (n.valid.data()[i] == 0.0f) mask.data()[i] = 1.0f;
  return mask;
}

// relMSE over the pixels where `mask` is 1: (x - r)^2 / (r^2 + eps), averaged over them and RGB; non-finite skipped.
struct MaskedError {
  double sum = 0;
  int64_t values = 0;
  void add(const Image& x, const Image& r, const Image& mask, double eps) {
    for (int64_t y = 0; y < mask.height(); ++y)
      for (int64_t px = 0; px < mask.width(); ++px) {
        if (mask.at(px, y) == 0.0f) continue;
        for (int c = 0; c < 3; ++c) {
          const double a = x.at(px, y, c), b = r.at(px, y, c);
          if (!std::isfinite(a) || !std::isfinite(b)) continue;
          sum += (a - b) * (a - b) / (b * b + eps);
          ++values;
        }
      }
  }
  double value() const { return values > 0 ? sum / static_cast<double>(values) : 0.0; }
};

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
  int64_t scored = 0, disoccluded_pixels = 0;
  MaskedError noisy_d, denoised_d;  // on the pixels a neighbouring frame does not show
  metrics::CompensatedTemporalRelMse noisy_c(o.eps), denoised_c(o.eps);  // along the motion (frames that have it)
  std::optional<AovStack> prev;  // the frame before, when it was scored
  Image prev_d;
  int64_t prev_f = 0;
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
    const bool follows = prev && prev_f == f - 1 && prev->width() == stack.width() && prev->height() == stack.height();
    if (follows && stack.motion) {
      noisy_c.add_map(compensated_temporal_map(stack, stack.color.image, *prev, prev->color.image, o.eps));
      if (den) denoised_c.add_map(compensated_temporal_map(stack, d, *prev, prev_d, o.eps));
    }
    const Image mask = disocclusion_mask(stack, in, f, o.input.load_options(), follows ? &*prev : nullptr);
    if (!mask.empty()) {
      int64_t count = 0;
      for (size_t i = 0; i < mask.size(); ++i) count += mask.data()[i] != 0.0f;
      disoccluded_pixels += count;
      noisy_d.add(stack.color.image, r, mask, o.eps);
      if (den) denoised_d.add(d, r, mask, o.eps);
      row["disoccluded_pixels"] = count;
    }
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
    prev = stack;
    prev_d = d;
    prev_f = f;
  } catch (const Error& e) {
    std::fprintf(stderr, "frame %lld  not scored: %s\n", static_cast<long long>(f), e.what());
    rows.push_back({{"frame", f}, {"error", e.what()}});
    failed.push_back(std::to_string(f));
    noisy_t.gap();
    denoised_t.gap();
    prev.reset();
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
  if (noisy_c.pixels() > 0) {
    doc["temporal_relmse_compensated"] = {{"noisy", noisy_c.value()}};
    if (den) doc["temporal_relmse_compensated"]["denoised"] = denoised_c.value();
    doc["temporal_compensated_formula"] =
        "mean over frame pairs, the pixels frame t-1 shows (along frame t's motion) and RGB of (e_t - W e_{t-1})^2 / "
        "((r_t^2 + (W r_{t-1})^2) / 2 + eps), e = x - r, W: bilinear warp from t-1 to t";
  }
  if (disoccluded_pixels > 0) {
    doc["disoccluded"] = {{"pixels", disoccluded_pixels}, {"noisy_relmse", noisy_d.value()}};
    if (den) doc["disoccluded"]["denoised_relmse"] = denoised_d.value();
    doc["disoccluded_formula"] = "relMSE over the pixels of each frame that frame t-1 or t+1 does not show (the motion "
                                 "AOV's reprojection: off screen, or another depth or normal there)";
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
    if (noisy_c.pixels() > 0) {
      std::printf("temporal relMSE, along the motion: noisy %.6f", noisy_c.value());
      if (den) std::printf(", denoised %.6f", denoised_c.value());
      std::printf("\n");
    }
    if (disoccluded_pixels > 0) {
      std::printf("disoccluded pixels (a neighbouring frame shows another surface): %lld, relMSE there: noisy %.6f",
                  static_cast<long long>(disoccluded_pixels), noisy_d.value());
      if (den) std::printf(", denoised %.6f", denoised_d.value());
      std::printf("\n");
    }
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
