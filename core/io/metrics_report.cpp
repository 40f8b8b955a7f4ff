#include "core/io/metrics_report.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/io/atomic_file.h"
#include "core/util/error.h"

// Number formats:
//  - JSON: finite doubles as JSON numbers, printed so that they parse back to the same double. JSON has no
//    infinity or NaN, so a non-finite score (PSNR of identical images is +inf) is written as the string
//    "inf",
//    "-inf" or "nan"; readers must accept a string there.
//  - CSV: shortest text that parses back to the same double (std::to_chars; as exact as %.17g, shorter), and
//    inf, -inf, nan for non-finite values. Fields with a comma, quote or line break are quoted, quotes
//    doubled.

namespace residue::io {
namespace fs = std::filesystem;
using nlohmann::ordered_json;

namespace {

std::string format_double(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  std::array<char, 32> buf{};
  return {buf.data(), std::to_chars(buf.data(), buf.data() + buf.size(), v).ptr};
}

ordered_json json_number(double v) {
  if (std::isfinite(v)) return v;
  return format_double(v);
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

const char* to_string(metrics::SsimSpace space) {
  return space == metrics::SsimSpace::Tonemapped ? "tonemapped" : "linear";
}

}  // namespace

std::string to_json(const MetricsReport& report) {
  ordered_json options;
  options["eps"] = json_number(report.options.eps);
  options["ssim_space"] = to_string(report.options.ssim_space);
  if (const auto& roi = report.options.roi)
    options["roi"] = {{"x", roi->x}, {"y", roi->y}, {"width", roi->width}, {"height", roi->height}};
  else
    options["roi"] = nullptr;

  ordered_json rows = ordered_json::array();
  for (const MetricsRow& row : report.rows) {
    const metrics::Scores& s = row.scores;
    rows.push_back({{"name", row.name},
                    {"test_file", row.test_file},
                    {"mse", json_number(s.mse)},
                    {"relmse", json_number(s.relmse)},
                    {"psnr", json_number(s.psnr)},
                    {"ssim", json_number(s.ssim)},
                    {"pixels", s.pixels},
                    {"excluded_test", s.excluded_test},
                    {"excluded_reference", s.excluded_reference},
                    {"hdr_flip", row.hdr_flip ? json_number(*row.hdr_flip) : ordered_json(nullptr)},
                    {"temporal_relmse_compensated", row.temporal_relmse_compensated
                                                        ? json_number(*row.temporal_relmse_compensated)
                                                        : ordered_json(nullptr)}});
  }

  ordered_json doc;
  doc["reference_file"] = report.reference_file;
  doc["width"] = report.width;
  doc["height"] = report.height;
  doc["options"] = std::move(options);
  doc["formula"] = metrics::formula_text(report.options);
  doc["rows"] = std::move(rows);
  if (report.flip)
    doc["flip"] = {{"exposures", {{"start", json_number(report.flip->start)}, {"stop", json_number(report.flip->stop)},
                                  {"count", report.flip->count}}},
                   {"pixels_per_degree", metrics::kFlipPixelsPerDegree},
                   {"definition", metrics::flip_formula_text(*report.flip)}};
  else
    doc["flip"] = nullptr;
  doc["notes"] = report.notes;
  // Replace invalid UTF-8 in file names rather than throwing.
  return doc.dump(2, ' ', false, ordered_json::error_handler_t::replace) + "\n";
}

std::string to_csv(const MetricsReport& report) {
  std::string out =
      "name,test_file,mse,relmse,psnr,ssim,pixels,excluded_test,excluded_reference,hdr_flip,temporal_relmse_compensated\n";
  for (const MetricsRow& row : report.rows) {
    const metrics::Scores& s = row.scores;
    out += csv_field(row.name) + "," + csv_field(row.test_file) + "," + format_double(s.mse) + "," +
           format_double(s.relmse) + "," + format_double(s.psnr) + "," + format_double(s.ssim) + "," +
           std::to_string(s.pixels) + "," + std::to_string(s.excluded_test) + "," +
           std::to_string(s.excluded_reference) + "," + (row.hdr_flip ? format_double(*row.hdr_flip) : std::string()) +
           "," + (row.temporal_relmse_compensated ? format_double(*row.temporal_relmse_compensated) : std::string()) + "\n";
  }
  return out;
}

namespace {

// ".json" or ".csv" (lower case); Error(Usage) for any other name.
std::string metrics_extension(const fs::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension != ".json" && extension != ".csv")
    throw Error(ErrorKind::Usage, "metrics file '" + path.string() + "' must end in .json or .csv");
  return extension;
}

}  // namespace

void prepare_metrics_output(const fs::path& path, bool overwrite) {
  metrics_extension(path);
  prepare_output(path, overwrite);
}

void write_metrics(const fs::path& path, const MetricsReport& report, bool overwrite) {
  const std::string text = metrics_extension(path) == ".json" ? to_json(report) : to_csv(report);

  write_atomically(path, overwrite, [&](const fs::path& temp) {
    std::ofstream file(temp, std::ios::binary | std::ios::trunc);
    file.write(text.data(), static_cast<std::streamsize>(text.size()));
    file.close();
    if (!file) throw Error(ErrorKind::Output, "cannot write '" + path.string() + "'");
  });
}

}  // namespace residue::io
