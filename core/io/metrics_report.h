// Metrics reports as JSON and CSV: one row per compared image (noisy, denoised, ...), with the formula and
// settings so that a number is never separated from its definition.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/metrics/metrics.h"

namespace residue::io {

struct MetricsRow {
  std::string name;        // "noisy", "denoised", ...
  std::string test_file;   // the image that was scored
  metrics::Scores scores;
};

struct MetricsReport {
  std::string reference_file;
  int64_t width = 0, height = 0;
  metrics::Options options;
  std::vector<MetricsRow> rows;
};

std::string to_json(const MetricsReport& report);  // pretty-printed
std::string to_csv(const MetricsReport& report);   // header line, one line per row

// Writes the report atomically; the format follows the extension (.json or .csv).
void write_metrics(const std::filesystem::path& path, const MetricsReport& report, bool overwrite);

}  // namespace residue::io
