// Histogram: how a map's (or an image's) values are spread, drawn as bars over a linear or log value axis with
// a log count axis (a few bright outliers and a million dark pixels both stay visible). The bars are coloured
// as the heatmap colours those values, and the part outside the colour range is counted at the ends.
#pragma once

#include <QWidget>
#include <memory>
#include <vector>

#include "core/image/colormap.h"
#include "core/image/image.h"

namespace residue::ui {

// The counts: `bins` bins between lo and hi (log-spaced when `log`); values below lo / above hi (and, for log,
// values <= 0) go to `below` / `above`; NaN and infinities to `invalid`. Channel 0 of `values`.
struct HistogramCounts {
  std::vector<int64_t> bins;
  int64_t below = 0, above = 0, invalid = 0;
};
HistogramCounts histogram_counts(const Image& values, double lo, double hi, bool log, int bins);

class Histogram : public QWidget {
  Q_OBJECT
 public:
  explicit Histogram(QWidget* parent = nullptr);
  // Counts `values` over the range, on the calling thread (a few milliseconds per megapixel).
  void setValues(std::shared_ptr<const Image> values, bool log, std::pair<double, double> range, Colormap map,
                 QString title);
  const HistogramCounts& counts() const { return counts_; }
  QSize sizeHint() const override { return {260, 110}; }
  QSize minimumSizeHint() const override { return {120, 70}; }

 protected:
  void paintEvent(class QPaintEvent*) override;

 private:
  HistogramCounts counts_;
  bool log_ = false;
  std::pair<double, double> range_{0, 1};
  Colormap map_ = Colormap::Viridis;
  QString title_;
};

}  // namespace residue::ui
