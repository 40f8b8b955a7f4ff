// Export all: everything a comparison produced, written into one folder in one go (worker thread):
//   <result>.exr                 every kept result (half, zip), with the source's metadata and residue:* provenance
//   heatmap-<result>.png / .exr  each result's error map against the reference: coloured with the colour bar and
//                                range drawn in, and as float values
//   metrics.json / metrics.csv   the scores of every result (and metrics-roi.* for a dragged region)
//   comparison.png               the comparison sheet (ui/comparison_sheet.h)
// A region's export (crop set) writes the same for the region alone: each result's pixels there (an EXR whose data
// window keeps its place in the frame, so it composites back), the noisy input's and the reference's, the maps
// cropped, and the region's scores as metrics.json / .csv; no sheet.
// Nothing is replaced unless asked: the files that would be are listed first (planned_files), and the writes
// themselves are atomic.
#pragma once

#include <QImage>
#include <QString>
#include <QStringList>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "core/aov/aov_stack.h"
#include "core/image/colormap.h"
#include "core/io/metrics_report.h"
#include "core/metrics/metrics.h"
#include "ui/result.h"

namespace residue::ui {

struct ExportAllInputs {
  std::shared_ptr<const AovStack> stack;  // the render (metadata and windows for the EXRs)
  std::vector<Result> results;
  std::shared_ptr<const Image> reference;  // null: no heatmaps
  metrics::Options options;
  // The heatmap of a result against the reference (HeatmapPanel::mapMaker); empty: relative squared error.
  std::function<Image(const Image& test, const Image& against)> make_map;
  QString map_name;  // "Relative squared error", for the colour bar's title
  Colormap colormap = Colormap::Viridis;
  ColorScale scale;
  io::MetricsReport whole, roi;  // roi.rows empty: no region
  std::function<QImage()> sheet;  // makes the comparison sheet (on the worker); empty: none
  bool results_exr = true, heatmaps = true, metrics = true, comparison = true;
  std::optional<Rect> crop;  // a region of the render (its data window's pixels): export that region alone
};

// "small fp32 (2)" -> "small_fp32_2": letters, digits, '.', '-' and '_' only.
QString file_stem(const QString& name);

// The files export_all would write into `folder`.
std::vector<std::filesystem::path> planned_files(const ExportAllInputs& in, const std::filesystem::path& folder);

// Writes them; returns an error message (the first failure, or the files that exist when not `overwrite`) or
// an empty string.
QString export_all(const ExportAllInputs& in, const std::filesystem::path& folder, bool overwrite);

// Writes one result as an EXR with what made it: a run's provenance as the CLI writes it (residue:model, its
// architecture, backend, post-steps, time), and residue:source, residue:result; an added file names itself; a
// result at a strength says it (residue:strength).
// With `crop`, `image` is that region of the render, written where it lies in the frame.
void write_result_exr(const std::filesystem::path& path, const Image& image, const AovStack& stack,
                      const Result& result, bool overwrite, bool half = true, const std::string& compression = "zip",
                      const std::optional<Rect>& crop = std::nullopt);

// Writes `image` as a PNG atomically (atomic_file.h); `what` names it in the error ("heatmap PNG").
void write_png(const std::filesystem::path& path, const QImage& image, bool overwrite, const std::string& what);

// A heatmap as a picture to keep: the coloured map with its colour bar, title and range below it.
QImage map_with_color_bar(const QImage& colored, Colormap colormap, std::pair<double, double> range, bool log,
                          const QString& title);

}  // namespace residue::ui
