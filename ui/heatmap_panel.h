// HeatmapPanel: per-pixel error maps (relative squared error, absolute error, squared error, SSIM) of the
// noisy or denoised colour against the reference, colour-mapped with core's colormaps (the same bytes an
// exported PNG holds), with a colour bar that shows the scale. Maps are computed on a worker thread.
#pragma once

#include <QImage>
#include <QWidget>
#include <memory>

#include "core/image/colormap.h"
#include "core/metrics/metrics.h"
#include "ui/latest_task.h"

class QCheckBox;
class QComboBox;
class QLineEdit;
class QSlider;

namespace residue::ui {

// A horizontal colour bar: the colormap from lo to hi with tick labels, linear or log.
class ColorBar : public QWidget {
  Q_OBJECT
 public:
  explicit ColorBar(QWidget* parent = nullptr);
  void setScale(Colormap map, double lo, double hi, bool log, QString title);
  QSize sizeHint() const override { return {260, 48}; }

 protected:
  void paintEvent(class QPaintEvent*) override;

 private:
  Colormap map_ = Colormap::Viridis;
  double lo_ = 0, hi_ = 1;
  bool log_ = false;
  QString title_;
};

class HeatmapPanel : public QWidget {
  Q_OBJECT
 public:
  enum class Display { Off, Pane, Overlay };
  enum class Of { Noisy, Denoised };

  explicit HeatmapPanel(QWidget* parent = nullptr);
  ~HeatmapPanel() override;

  // Recomputes the map of `test` against `reference` (whole image) on a worker thread; ready() follows.
  void compute(std::shared_ptr<const Image> noisy, std::shared_ptr<const Image> denoised,
               std::shared_ptr<const Image> reference, const metrics::Options& options);

  Display display() const;
  Of of() const;
  metrics::MapKind kind() const;
  Colormap colormap() const;
  ColorScale scale() const;  // as set: log and the range (automatic bounds unset)
  std::pair<double, double> range() const { return range_; }  // resolved bounds of the current image
  std::shared_ptr<const Image> map() const { return map_; }   // one channel, image-sized; null when none
  const QImage& image() const { return image_; }               // the colour-mapped map
  QString title() const;                                       // e.g. "rse of denoised (log)"
  bool busy() const;

  void setKind(metrics::MapKind kind);
  void setOf(Of of);
  void setDisplay(Display d);
  void setColormap(Colormap map);
  void setLog(bool log);
  void setRange(std::optional<double> lo, std::optional<double> hi);

 signals:
  void settingsChanged();  // what the map shows changed: the owner calls compute() again
  void displayChanged();   // pane / overlay / off
  void ready();            // image() and map() are new

 private:
  void recolor();

  QComboBox* kind_ = nullptr;
  QComboBox* of_ = nullptr;
  QComboBox* display_ = nullptr;
  QComboBox* colormap_ = nullptr;
  QCheckBox* log_ = nullptr;
  QLineEdit* lo_ = nullptr;
  QLineEdit* hi_ = nullptr;
  ColorBar* bar_ = nullptr;

  struct Result {
    std::shared_ptr<const Image> map;
    QImage image;
    std::pair<double, double> range;
    QString error;
  };
  std::unique_ptr<LatestTask<Result>> task_;
  std::shared_ptr<const Image> map_;
  QImage image_;
  std::pair<double, double> range_{0, 1};
};

// A one-channel map coloured by core's apply_colormap, as a QImage (RGB32).
QImage colorize(const Image& map, Colormap colormap, const ColorScale& scale);

}  // namespace residue::ui
