#include "ui/histogram.h"

#include <QPainter>
#include <algorithm>
#include <cmath>

namespace residue::ui {

HistogramCounts histogram_counts(const Image& values, double lo, double hi, bool log, int bins) {
  HistogramCounts h;
  h.bins.assign(static_cast<size_t>(std::max(1, bins)), 0);
  const bool usable = hi > lo && (!log || lo > 0);
  const double a = log && usable ? std::log(lo) : lo, b = log && usable ? std::log(hi) : hi;
  const double scale = usable ? static_cast<double>(h.bins.size()) / (b - a) : 0.0;
  for (int64_t y = 0; y < values.height(); ++y) {
    for (int64_t x = 0; x < values.width(); ++x) {
      const double v = values.at(x, y, 0);
      if (!std::isfinite(v)) {
        ++h.invalid;
      } else if (!usable || v < lo || (log && v <= 0)) {
        ++h.below;
      } else if (v > hi) {
        ++h.above;
      } else {
        const double t = ((log ? std::log(v) : v) - a) * scale;
        ++h.bins[std::min(h.bins.size() - 1, static_cast<size_t>(std::max(0.0, t)))];
      }
    }
  }
  return h;
}

Histogram::Histogram(QWidget* parent) : QWidget(parent) { setObjectName("histogram"); }

void Histogram::setValues(std::shared_ptr<const Image> values, bool log, std::pair<double, double> range, Colormap map,
                          QString title) {
  log_ = log;
  range_ = range;
  map_ = map;
  title_ = std::move(title);
  counts_ = values ? histogram_counts(*values, range.first, range.second, log, 64) : HistogramCounts{};
  update();
}

void Histogram::paintEvent(QPaintEvent*) {
  QPainter p(this);
  const QColor text = palette().color(QPalette::WindowText);
  const QFontMetrics fm = p.fontMetrics();
  const int th = fm.height();
  p.setPen(text);
  p.drawText(QRect(4, 0, width() - 8, th), Qt::AlignLeft | Qt::AlignVCenter,
             fm.elidedText(title_, Qt::ElideRight, width() - 8));
  if (counts_.bins.empty()) return;
  const QRect plot(4, th + 2, width() - 8, std::max(10, height() - 2 * th - 6));
  const int64_t most = std::max<int64_t>(1, *std::max_element(counts_.bins.begin(), counts_.bins.end()));
  const double top = std::log10(static_cast<double>(most) + 1.0);
  const int n = static_cast<int>(counts_.bins.size());
  for (int i = 0; i < n; ++i) {
    if (counts_.bins[static_cast<size_t>(i)] == 0) continue;
    // Log counts: log10(count + 1) over log10(most + 1).
    const double f = std::log10(static_cast<double>(counts_.bins[static_cast<size_t>(i)]) + 1.0) / top;
    const int x0 = plot.left() + i * plot.width() / n, x1 = plot.left() + (i + 1) * plot.width() / n;
    const int h = std::max(1, static_cast<int>(std::lround(f * plot.height())));
    const auto c = colormap_lookup(map_, (i + 0.5) / n);
    p.fillRect(QRect(x0, plot.bottom() - h + 1, std::max(1, x1 - x0), h), QColor(c[0], c[1], c[2]));
  }
  p.setPen(text);
  p.drawLine(plot.bottomLeft(), plot.bottomRight());
  const auto label = [](double v) { return QString::number(v, 'g', 3); };
  const int ty = plot.bottom() + 2;
  p.drawText(QRect(plot.left(), ty, plot.width() / 2, th), Qt::AlignLeft,
             QString("%1%2").arg(label(range_.first), counts_.below ? QString(" (+%1 below)").arg(counts_.below) : ""));
  p.drawText(QRect(plot.left() + plot.width() / 2, ty, plot.width() / 2, th), Qt::AlignRight,
             QString("%1%2").arg(counts_.above ? QString("(+%1 above) ").arg(counts_.above) : "", label(range_.second)));
}

}  // namespace residue::ui
