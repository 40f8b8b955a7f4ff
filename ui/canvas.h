// ImageCanvas: draws one or more panes of the same pixel grid with one zoom and pan, so that every pane shows
// the same pixels: all in a grid, a single pane, two side by side, or a wipe (A left of a split, B right of it).
// It only draws what it is given (display-encoded QImages, made by DisplayTransform on worker threads) and
// reports what the user does with the mouse: the pixel under the cursor, a dragged region of interest.
#pragma once

#include <QFontMetrics>
#include <QImage>
#include <QWidget>
#include <memory>
#include <optional>
#include <vector>

#include "core/image/image.h"

namespace residue::ui {

struct Pane {
  QString label;                        // drawn in the pane's corner
  QImage display;                       // display-encoded pixels (may be null while rendering)
  int display_scale = 1;                // image pixels per display pixel (> 1 for a quick preview)
  std::shared_ptr<const Image> values;  // linear values, for the per-pixel text when zoomed in (may be null)
  int first_channel = 0;
  int channel_count = 3;
  QImage overlay;                       // drawn over `display` with overlayOpacity (a heatmap), may be null
  QString placeholder;                  // said in the pane while `display` is null
};

class ImageCanvas : public QWidget {
  Q_OBJECT
 public:
  // SideBySide: every pane, in a grid; Single: the current pane; Pair: A and B of the wipe pair side by side;
  // Wipe: A left of a split, B right of it.
  enum class Layout { SideBySide, Single, Pair, Wipe };

  explicit ImageCanvas(QWidget* parent = nullptr);

  // Replaces the panes; the view (zoom, pan) is kept when the image size is unchanged, else fitted.
  void setPanes(std::vector<Pane> panes, QSize image_size);
  const std::vector<Pane>& panes() const { return panes_; }
  // Paints `pixels` (display-encoded) into pane `index` at `at` (image coordinates), e.g. a finished tile.
  void patchPane(int index, QPoint at, const QImage& pixels);
  void setPaneValues(int index, std::shared_ptr<const Image> values);
  void setPaneDisplay(int index, QImage display);
  void setPaneLabel(int index, QString label);
  void setPanePlaceholder(int index, QString placeholder);
  void setOverlay(int index, QImage overlay);  // null clears it
  void clearOverlays();

  void setLayout(Layout layout);
  Layout layout() const { return layout_; }
  void setCurrent(int index);  // the pane shown in Single layout
  int current() const { return current_; }
  void setWipePair(int a, int b);
  int wipeA() const { return wipe_a_; }
  int wipeB() const { return wipe_b_; }
  void flipAB();  // in Single layout: show the other of the wipe pair
  void setWipePosition(double fraction);  // 0..1 of the pane width
  void setOverlayOpacity(double opacity);

  // View.
  void fit();
  void oneToOne();
  void zoomBy(double factor);                       // about the centre of the first visible pane
  void zoomAbout(double factor, QPointF widget_pos);
  double zoom() const { return zoom_; }             // screen pixels per image pixel
  QPointF center() const { return center_; }
  void setView(double zoom, QPointF center);
  bool autoFit() const { return auto_fit_; }        // fitted, and following the widget's size

  // Region of interest in image pixels; empty = none.
  void setRoi(std::optional<Rect> roi);
  std::optional<Rect> roi() const { return roi_; }

  // The image pixel under a widget position, when it is inside a pane and the image.
  std::optional<QPoint> pixelAt(QPointF widget_pos) const;
  // The pane (index in panes()) under a widget position, and the one under the mouse as last hovered.
  std::optional<int> paneAt(QPointF widget_pos) const;
  std::optional<int> hoveredPane() const { return hovered_pane_; }
  // Pane rectangles in widget coordinates, in the order drawn (for tests and screenshots).
  std::vector<QRect> paneRects() const;

  // Zoom at which each pixel gets its values written in it.
  static constexpr double kValueTextZoom = 48.0;
  static constexpr double kZoomStep = 1.4142135623730951;  // + and -: half a stop
  // A pixel's value as written in its cell: as many significant digits (4 at most) as fit `width` pixels; empty
  // when not even one does.
  static QString fittedValueText(double value, double width, const QFontMetrics& fm);

 signals:
  void hovered(std::optional<QPoint> pixel);
  void roiChanged(std::optional<residue::Rect> roi);
  void viewChanged();
  void filesDropped(QStringList files);

 protected:
  void paintEvent(QPaintEvent*) override;
  void wheelEvent(QWheelEvent*) override;
  void mousePressEvent(QMouseEvent*) override;
  void mouseMoveEvent(QMouseEvent*) override;
  void mouseReleaseEvent(QMouseEvent*) override;
  void leaveEvent(QEvent*) override;
  void resizeEvent(QResizeEvent*) override;
  void dragEnterEvent(QDragEnterEvent*) override;
  void dropEvent(QDropEvent*) override;

 private:
  struct Slot {
    int pane;
    QRect rect;       // widget area the pane may draw in
    QRect clip;       // part of rect it draws in (wipe halves)
  };
  std::vector<Slot> paneSlots() const;
  std::vector<std::pair<int, QRect>> gridRects(const std::vector<int>& panes) const;
  QPointF toImage(const QRect& pane_rect, QPointF widget_pos) const;
  QPointF toWidget(const QRect& pane_rect, QPointF image_pos) const;
  void drawPane(class QPainter& p, const Slot& s) const;
  void drawValues(class QPainter& p, const Slot& s, const Pane& pane, const QRect& label) const;
  void drawRoi(class QPainter& p, const Slot& s) const;
  int wipeSplitX() const;
  void clampView();
  // Says again what is under the mouse after the view changed under it (a zoom, a flip, another layout), so that
  // the status bar and the Pixel panel do not wait for the next mouse move.
  void rehover();

  std::vector<Pane> panes_;
  std::optional<int> hovered_pane_;
  std::optional<QPointF> mouse_;  // where the mouse is over the canvas, if it is
  QSize image_size_;
  Layout layout_ = Layout::SideBySide;
  int current_ = 0;
  int wipe_a_ = 0, wipe_b_ = 1;
  double wipe_position_ = 0.5;
  double overlay_opacity_ = 0.6;
  double zoom_ = 1.0;
  QPointF center_;
  bool fitted_ = false;
  bool auto_fit_ = true;  // follows the widget's size until the user zooms or pans
  std::optional<Rect> roi_;

  enum class Drag { None, Pan, Roi, Wipe };
  Drag drag_ = Drag::None;
  QPointF drag_last_;
  QPointF roi_anchor_;  // image coordinates
};

}  // namespace residue::ui
