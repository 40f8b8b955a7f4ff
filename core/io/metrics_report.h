// Metrics reports as JSON and CSV: one row per compared image (noisy, denoised, ...), with the formula and
// settings so that a number is never separated from its definition.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/metrics/flip.h"
#include "core/metrics/metrics.h"

namespace residue::io {

struct MetricsRow {
  std::string name;        // "noisy", "denoised", ...
  std::string test_file;   // the image that was scored
  metrics::Scores scores;
  std::optional<double> hdr_flip;  // HDR-FLIP's mean (core/metrics/flip.h) over the scores' region, when computed
  // A frame of a sequence: the temporal relMSE along the motion against the same result on frame t-1
  // (metrics::CompensatedTemporalRelMse, core/metrics/temporal.h) over the whole image, when computed.
  std::optional<double> temporal_relmse_compensated;
};

struct MetricsReport {
  std::string reference_file;
  int64_t width = 0, height = 0;
  metrics::Options options;
  std::vector<MetricsRow> rows;
  std::vector<std::string> notes;  // what the loader assumed or left out (e.g. pixels the reference lacks)
  std::optional<metrics::FlipExposures> flip;  // the exposures HDR-FLIP used, when the rows have it
};

// Pretty-printed: reference_file, width, height, options {eps, ssim_space, roi (null or {x,y,width,height})},
// formula (metrics::formula_text), rows (hdr_flip and temporal_relmse_compensated: a number, or null when not
// computed), flip (null, or its
// exposures and definition) and notes. Finite numbers parse back to the same double. JSON has no infinity
// or NaN: a non-finite score (PSNR of identical images is +inf) is written as the string "inf", "-inf" or "nan".
std::string to_json(const MetricsReport& report);
// Header `name,test_file,mse,relmse,psnr,ssim,pixels,excluded_test,excluded_reference,hdr_flip,
// temporal_relmse_compensated`, one line per row (the last two empty when not computed);
// doubles as the shortest text that parses back to the same value (inf, -inf, nan when not finite); fields with
// a comma, quote or line break are quoted ("" for a quote).
std::string to_csv(const MetricsReport& report);

// write_metrics()'s checks, for a caller to run before long work: a .json or .csv name (else Error(Usage)) and
// prepare_output()'s (atomic_file.h).
void prepare_metrics_output(const std::filesystem::path& path, bool overwrite);

// Writes the report atomically; the format follows the extension (.json or .csv, any case), else
// residue::Error(Usage).
void write_metrics(const std::filesystem::path& path, const MetricsReport& report, bool overwrite);

}  // namespace residue::io
