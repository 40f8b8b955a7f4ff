// HeatmapPanel: per-pixel error maps (relative squared error, absolute error, squared error, SSIM) of result A,
// result B or the noisy input against the reference, or of A against B, colour-mapped with core's colormaps,
// with a colour bar that shows the scale and a histogram of the values. The range is by default the same fixed
// one for every result, so that two results' maps can be compared by eye; "this map's own" fits each map.
// Maps are computed on a worker thread.
#pragma once

#include <QImage>
#include <QWidget>
#include <functional>
#include <memory>

#include "core/image/colormap.h"
#include "core/metrics/metrics.h"
#include "ui/latest_task.h"

class QCheckBox;
class QComboBox;
class QLineEdit;
class QSlider;

namespace residue::ui {

// Draws a colour bar into `area`: the title, the colormap from lo to hi, ticks at both ends and the middle.
void paint_color_bar(class QPainter& p, QRect area, Colormap map, double lo, double hi, bool log,
                     const QString& title, const QColor& text);

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
  enum class Of { A, B, Noisy, AgainstB };  // B, AgainstB: need a result B

  explicit HeatmapPanel(QWidget* parent = nullptr);
  ~HeatmapPanel() override;

  // Recomputes the map of `test` against `against` (whole image) on a worker thread; ready() follows.
  // `subject` names what is mapped in the title ("small fp32", "small fp32 against base fp32"); `missing` is
  // said when `test` or `against` is null.
  void compute(std::shared_ptr<const Image> test, std::shared_ptr<const Image> against, const QString& subject,
               const QString& missing, const metrics::Options& options);
  // The same for a map `make` computes on the worker (the temporal map); null `make`: `missing` is said.
  void computeMap(std::function<Image()> make, const QString& subject, const QString& missing);
  // The map chosen is the temporal error along the motion (frames of a sequence), not one of kind().
  bool temporal() const;
  // The map chosen is HDR-FLIP's (core/metrics/flip.h; magma over [0, 1] as NVIDIA's tool shows it).
  bool flip() const;
  // The map chosen, as a function of a test image and the image it is compared with (export writes it for every
  // result); the temporal map, which needs the frames, is exported as relative squared error.
  std::function<Image(const Image& test, const Image& against)> mapMaker(const metrics::Options& options) const;
  // The map as a picture to keep: the colour-mapped image with the colour bar, title and range below it.
  QImage imageWithBar() const;
  // The fixed range every result's map shares, per kind (what "the same for every result" uses).
  static std::pair<double, double> sharedRange(metrics::MapKind kind);

  Display display() const;
  Of of() const;
  metrics::MapKind kind() const;  // the temporal map reads as relative squared error, FLIP's as SSIM's [0, 1]
  Colormap colormap() const;
  ColorScale scale() const;  // as set: log and the range (shared, typed, or unset for this map's own)
  bool sharedScale() const;  // the range is the fixed one every result shares
  std::pair<double, double> range() const { return range_; }  // resolved bounds of the current image
  std::shared_ptr<const Image> map() const { return map_; }   // one channel, image-sized; null when none
  const QImage& image() const { return image_; }               // the colour-mapped map
  QString title() const;  // e.g. "Relative squared error of small fp32 (log)", for the map shown
  // What the heatmap pane says while it has no map: the title and why there is none ("no reference"), or that it
  // is being computed.
  QString placeholder() const;
  bool busy() const;

  void setKind(metrics::MapKind kind);
  void setTemporal();  // the temporal map (setKind picks one of the others)
  void setFlip();      // HDR-FLIP's map
  void setOf(Of of);
  void setDisplay(Display d);
  void setColormap(Colormap map);
  void setLog(bool log);
  void setRange(std::optional<double> lo, std::optional<double> hi);  // typed bounds; none: the range mode's
  void setSharedScale(bool shared);

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
  QComboBox* range_mode_ = nullptr;
  QCheckBox* log_ = nullptr;
  QLineEdit* lo_ = nullptr;
  QLineEdit* hi_ = nullptr;
  ColorBar* bar_ = nullptr;
  class Histogram* histogram_ = nullptr;
  QString subject_;  // what the current map is of
  QString missing_;  // why there is no map (computeMap without `make`), until the next map is asked for

  struct Result {
    QString subject;
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
