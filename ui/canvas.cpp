#include "ui/canvas.h"

#include <QDragEnterEvent>
#include <QMimeData>
#include <QMouseEvent>
#include <QPainter>
#include <QWheelEvent>
#include <algorithm>
#include <cmath>

namespace residue::ui {

namespace {
constexpr int kGap = 2;               // pixels between side-by-side panes
constexpr double kMinZoom = 1.0 / 64.0;
constexpr double kMaxZoom = 256.0;
constexpr int kWipeGrab = 6;          // how close to the split line a press grabs it
}  // namespace

ImageCanvas::ImageCanvas(QWidget* parent) : QWidget(parent) {
  setMouseTracking(true);
  setAcceptDrops(true);
  setFocusPolicy(Qt::StrongFocus);
  setMinimumSize(320, 200);
  setAttribute(Qt::WA_OpaquePaintEvent);
  connect(this, &ImageCanvas::viewChanged, this, &ImageCanvas::rehover);
}

void ImageCanvas::rehover() {
  if (!mouse_) return;
  hovered_pane_ = paneAt(*mouse_);
  emit hovered(pixelAt(*mouse_));
}

void ImageCanvas::setPanes(std::vector<Pane> panes, QSize image_size) {
  const bool same_size = image_size == image_size_;
  const bool same_count = panes.size() == panes_.size();
  panes_ = std::move(panes);
  image_size_ = image_size;
  const int n = static_cast<int>(panes_.size());
  current_ = std::clamp(current_, 0, std::max(0, n - 1));
  wipe_a_ = std::clamp(wipe_a_, 0, std::max(0, n - 1));
  wipe_b_ = std::clamp(wipe_b_, 0, std::max(0, n - 1));
  // A fitted view follows the panes: more panes are smaller.
  if (!same_size || !fitted_ || (auto_fit_ && !same_count)) fit();
  update();
  rehover();
}

void ImageCanvas::patchPane(int index, QPoint at, const QImage& pixels) {
  if (index < 0 || index >= static_cast<int>(panes_.size())) return;
  QImage& d = panes_[static_cast<size_t>(index)].display;
  if (d.isNull() || panes_[static_cast<size_t>(index)].display_scale != 1) return;  // a preview: the full image follows
  QPainter p(&d);
  p.setCompositionMode(QPainter::CompositionMode_Source);
  p.drawImage(at, pixels);
  p.end();
  update();
}

void ImageCanvas::setPaneValues(int index, std::shared_ptr<const Image> values) {
  if (index < 0 || index >= static_cast<int>(panes_.size())) return;
  panes_[static_cast<size_t>(index)].values = std::move(values);
}

void ImageCanvas::setPaneDisplay(int index, QImage display) {
  if (index < 0 || index >= static_cast<int>(panes_.size())) return;
  panes_[static_cast<size_t>(index)].display = std::move(display);
  update();
}

void ImageCanvas::setPaneLabel(int index, QString label) {
  if (index < 0 || index >= static_cast<int>(panes_.size())) return;
  panes_[static_cast<size_t>(index)].label = std::move(label);
  update();
}

void ImageCanvas::setPanePlaceholder(int index, QString placeholder) {
  if (index < 0 || index >= static_cast<int>(panes_.size())) return;
  panes_[static_cast<size_t>(index)].placeholder = std::move(placeholder);
  update();
}

void ImageCanvas::setOverlay(int index, QImage overlay) {
  if (index < 0 || index >= static_cast<int>(panes_.size())) return;
  panes_[static_cast<size_t>(index)].overlay = std::move(overlay);
  update();
}

void ImageCanvas::clearOverlays() {
  for (auto& p : panes_) p.overlay = QImage();
  update();
}

void ImageCanvas::setLayout(Layout layout) {
  layout_ = layout;
  if (auto_fit_) fit();  // the pane size changed
  update();
  emit viewChanged();
}

void ImageCanvas::setCurrent(int index) {
  if (index < 0 || index >= static_cast<int>(panes_.size())) return;
  current_ = index;
  update();
  rehover();
}

void ImageCanvas::setWipePair(int a, int b) {
  const int n = static_cast<int>(panes_.size());
  if (a < 0 || b < 0 || a >= n || b >= n) return;
  wipe_a_ = a;
  wipe_b_ = b;
  update();
  rehover();
}

void ImageCanvas::flipAB() {
  current_ = current_ == wipe_a_ ? wipe_b_ : wipe_a_;
  update();
  rehover();
}

void ImageCanvas::setWipePosition(double fraction) {
  wipe_position_ = std::clamp(fraction, 0.0, 1.0);
  update();
}

void ImageCanvas::setOverlayOpacity(double opacity) {
  overlay_opacity_ = std::clamp(opacity, 0.0, 1.0);
  update();
}

std::vector<ImageCanvas::Slot> ImageCanvas::paneSlots() const {
  std::vector<Slot> out;
  const int n = static_cast<int>(panes_.size());
  if (n == 0) return out;
  const QRect all = rect();
  switch (layout_) {
    case Layout::SideBySide: {
      std::vector<int> all_panes(static_cast<size_t>(n));
      for (int i = 0; i < n; ++i) all_panes[static_cast<size_t>(i)] = i;
      for (const auto& [i, r] : gridRects(all_panes)) out.push_back({i, r, r});
      break;
    }
    case Layout::Pair:
      for (const auto& [i, r] : gridRects({wipe_a_, wipe_b_})) out.push_back({i, r, r});
      break;
    case Layout::Single: out.push_back({current_, all, all}); break;
    case Layout::Wipe: {
      const int split = wipeSplitX();
      out.push_back({wipe_a_, all, QRect(all.left(), all.top(), split - all.left(), all.height())});
      out.push_back({wipe_b_, all, QRect(split, all.top(), all.right() - split + 1, all.height())});
      break;
    }
  }
  return out;
}

// The panes in a grid of the column count that shows the image largest: four square renders on a wide
// screen go 2 x 2, three go in a row.
std::vector<std::pair<int, QRect>> ImageCanvas::gridRects(const std::vector<int>& panes) const {
  const int n = static_cast<int>(panes.size());
  const QRect all = rect();
  const double iw = std::max(1, image_size_.width()), ih = std::max(1, image_size_.height());
  int best_columns = n;
  double best_zoom = -1;
  for (int columns = 1; columns <= n; ++columns) {
    const int rows = (n + columns - 1) / columns;
    const double w = (all.width() - kGap * (columns - 1)) / static_cast<double>(columns);
    const double h = (all.height() - kGap * (rows - 1)) / static_cast<double>(rows);
    const double z = std::min(w / iw, h / ih);
    if (z > best_zoom + 1e-9) {
      best_zoom = z;
      best_columns = columns;
    }
  }
  const int columns = best_columns, rows = (n + columns - 1) / columns;
  const int w = (all.width() - kGap * (columns - 1)) / columns;
  const int h = (all.height() - kGap * (rows - 1)) / rows;
  std::vector<std::pair<int, QRect>> out;
  for (int k = 0; k < n; ++k)
    out.emplace_back(panes[static_cast<size_t>(k)],
                     QRect(all.x() + (k % columns) * (w + kGap), all.y() + (k / columns) * (h + kGap), w, h));
  return out;
}

std::vector<QRect> ImageCanvas::paneRects() const {
  std::vector<QRect> r;
  for (const auto& s : paneSlots()) r.push_back(s.clip);
  return r;
}

int ImageCanvas::wipeSplitX() const {
  return rect().left() + static_cast<int>(std::lround(wipe_position_ * rect().width()));
}

QPointF ImageCanvas::toImage(const QRect& pane_rect, QPointF widget_pos) const {
  const QPointF c(pane_rect.x() + pane_rect.width() / 2.0, pane_rect.y() + pane_rect.height() / 2.0);
  return center_ + (widget_pos - c) / zoom_;
}

QPointF ImageCanvas::toWidget(const QRect& pane_rect, QPointF image_pos) const {
  const QPointF c(pane_rect.x() + pane_rect.width() / 2.0, pane_rect.y() + pane_rect.height() / 2.0);
  return c + (image_pos - center_) * zoom_;
}

void ImageCanvas::fit() {
  fitted_ = true;
  auto_fit_ = true;
  if (image_size_.isEmpty()) return;
  const auto s = paneSlots();
  const QRect r = s.empty() ? rect() : s.front().rect;
  const double z = std::min(r.width() / static_cast<double>(image_size_.width()),
                            r.height() / static_cast<double>(image_size_.height()));
  zoom_ = std::clamp(z, kMinZoom, kMaxZoom);
  center_ = QPointF(image_size_.width() / 2.0, image_size_.height() / 2.0);
  update();
  emit viewChanged();
}

void ImageCanvas::oneToOne() {
  auto_fit_ = false;
  zoom_ = 1.0;
  clampView();
  update();
  emit viewChanged();
}

void ImageCanvas::zoomBy(double factor) {
  const auto s = paneSlots();
  if (s.empty()) return;
  zoomAbout(factor, QPointF(s.front().rect.center()));
}

void ImageCanvas::zoomAbout(double factor, QPointF widget_pos) {
  // Keep the image point under `widget_pos` where it is.
  for (const auto& s : paneSlots()) {
    if (!s.rect.contains(widget_pos.toPoint())) continue;
    const QPointF img = toImage(s.rect, widget_pos);
    auto_fit_ = false;
    zoom_ = std::clamp(zoom_ * factor, kMinZoom, kMaxZoom);
    const QPointF c(s.rect.x() + s.rect.width() / 2.0, s.rect.y() + s.rect.height() / 2.0);
    center_ = img - (widget_pos - c) / zoom_;
    clampView();
    update();
    emit viewChanged();
    return;
  }
}

void ImageCanvas::setView(double zoom, QPointF center) {
  zoom_ = std::clamp(zoom, kMinZoom, kMaxZoom);
  center_ = center;
  fitted_ = true;
  auto_fit_ = false;
  clampView();
  update();
  emit viewChanged();
}

void ImageCanvas::clampView() {
  // The centre stays on the image so that it can never be panned out of sight.
  center_.setX(std::clamp(center_.x(), 0.0, static_cast<double>(image_size_.width())));
  center_.setY(std::clamp(center_.y(), 0.0, static_cast<double>(image_size_.height())));
}

void ImageCanvas::setRoi(std::optional<Rect> roi) {
  if (roi && roi->empty()) roi.reset();
  roi_ = roi;
  update();
}

std::optional<QPoint> ImageCanvas::pixelAt(QPointF widget_pos) const {
  for (const auto& s : paneSlots()) {
    if (!s.clip.contains(widget_pos.toPoint())) continue;
    const QPointF img = toImage(s.rect, widget_pos);
    const int x = static_cast<int>(std::floor(img.x())), y = static_cast<int>(std::floor(img.y()));
    if (x < 0 || y < 0 || x >= image_size_.width() || y >= image_size_.height()) return std::nullopt;
    return QPoint(x, y);
  }
  return std::nullopt;
}

std::optional<int> ImageCanvas::paneAt(QPointF widget_pos) const {
  for (const auto& s : paneSlots())
    if (s.clip.contains(widget_pos.toPoint())) return s.pane;
  return std::nullopt;
}

void ImageCanvas::paintEvent(QPaintEvent*) {
  QPainter p(this);
  p.fillRect(rect(), QColor(38, 38, 38));
  if (panes_.empty()) {
    p.setPen(QColor(170, 170, 170));
    p.drawText(rect(), Qt::AlignCenter, tr("Open a render (Ctrl+O) or drop EXR files here"));
    return;
  }
  for (const auto& s : paneSlots()) drawPane(p, s);
  if (layout_ == Layout::Wipe) {
    const int x = wipeSplitX();
    p.setPen(QPen(QColor(255, 255, 255, 200), 1));
    p.drawLine(x, rect().top(), x, rect().bottom());
  }
}

void ImageCanvas::drawPane(QPainter& p, const Slot& s) const {
  const Pane& pane = panes_[static_cast<size_t>(s.pane)];
  p.save();
  p.setClipRect(s.clip);
  if (!pane.display.isNull()) {
    // Draw only the visible source pixels: a zoomed-in view of a large image then costs what the screen costs.
    const QPointF tl = toImage(s.rect, QPointF(s.clip.topLeft()));
    const QPointF br = toImage(s.rect, QPointF(s.clip.bottomRight()) + QPointF(1, 1));
    // In display pixels, which are display_scale image pixels wide for a preview.
    const double k = pane.display_scale;
    const int x0 = std::max(0, static_cast<int>(std::floor(tl.x() / k)));
    const int y0 = std::max(0, static_cast<int>(std::floor(tl.y() / k)));
    const int x1 = std::min(pane.display.width(), static_cast<int>(std::ceil(br.x() / k)));
    const int y1 = std::min(pane.display.height(), static_cast<int>(std::ceil(br.y() / k)));
    if (x1 > x0 && y1 > y0) {
      const QRect src(x0, y0, x1 - x0, y1 - y0);
      const QRectF dst(toWidget(s.rect, QPointF(x0 * k, y0 * k)), toWidget(s.rect, QPointF(x1 * k, y1 * k)));
      // Below 1:1, smooth sampling avoids aliasing; above, nearest neighbour shows the pixels.
      p.setRenderHint(QPainter::SmoothPixmapTransform, zoom_ < 1.0);
      p.drawImage(dst, pane.display, src);
      if (!pane.overlay.isNull()) {
        p.setOpacity(overlay_opacity_);
        p.drawImage(dst, pane.overlay, src);
        p.setOpacity(1.0);
      }
    }
  }
  // Label, on a dark plate so it reads over any image. A long one wraps onto a second line rather than losing its
  // middle ("Relative squared e...of oidn fp32"); only what is longer still is shortened, at its end.
  const QFontMetrics fm(font());
  const int width = std::max(40, s.clip.width() - 24);
  QString label = pane.label;
  QRect text = fm.boundingRect(QRect(0, 0, width, 10000), Qt::TextWordWrap, label);
  if (text.height() > 2 * fm.lineSpacing()) {
    while (label.size() > 1 && fm.boundingRect(QRect(0, 0, width, 10000), Qt::TextWordWrap, label + "...").height() >
                                   2 * fm.lineSpacing())
      label.chop(1);
    label += "...";
    text = fm.boundingRect(QRect(0, 0, width, 10000), Qt::TextWordWrap, label);
  }
  QRect box = text.adjusted(-5, -3, 5, 3);
  box.moveTopLeft(s.clip.topLeft() + QPoint(6, 6));
  if (layout_ == Layout::Wipe && s.pane == wipe_b_) box.moveTopRight(s.clip.topRight() + QPoint(-6, 6));
  if (!pane.display.isNull() && zoom_ >= kValueTextZoom && pane.values) drawValues(p, s, pane, box);
  if (pane.display.isNull()) {
    p.setPen(QColor(150, 150, 150));
    p.drawText(s.rect, Qt::AlignCenter,
               pane.placeholder.isEmpty() ? tr("%1\n(not available)").arg(pane.label) : pane.placeholder);
  }
  drawRoi(p, s);
  p.fillRect(box, QColor(0, 0, 0, 150));
  p.setPen(Qt::white);
  p.drawText(box, Qt::AlignCenter | Qt::TextWordWrap, label);
  p.restore();
}

QString ImageCanvas::fittedValueText(double value, double width, const QFontMetrics& fm) {
  for (int digits = 4; digits >= 1; --digits) {
    const QString text = QString::number(value, 'g', digits);
    if (fm.horizontalAdvance(text) <= width) return text;
  }
  return {};
}

void ImageCanvas::drawValues(QPainter& p, const Slot& s, const Pane& pane, const QRect& label) const {
  const Image& v = *pane.values;
  const QPointF tl = toImage(s.rect, QPointF(s.clip.topLeft()));
  const QPointF br = toImage(s.rect, QPointF(s.clip.bottomRight()));
  const int64_t x0 = std::max<int64_t>(0, static_cast<int64_t>(std::floor(tl.x())));
  const int64_t y0 = std::max<int64_t>(0, static_cast<int64_t>(std::floor(tl.y())));
  const int64_t x1 = std::min<int64_t>(v.width() - 1, static_cast<int64_t>(std::floor(br.x())));
  const int64_t y1 = std::min<int64_t>(v.height() - 1, static_cast<int64_t>(std::floor(br.y())));
  const int count = std::min(pane.channel_count, v.channels() - pane.first_channel);
  // A line per channel, in a font that fits it; a value too wide for its cell is written with fewer digits
  // (fittedValueText), never across the next cell.
  QFont f = font();
  f.setPixelSize(std::clamp(static_cast<int>(zoom_ / (count + 1) * 0.8), 6, 15));
  p.setFont(f);
  const QFontMetrics fm(f);
  static const QColor kChannelColors[] = {QColor(255, 120, 120), QColor(120, 230, 120), QColor(130, 170, 255)};
  for (int64_t y = y0; y <= y1; ++y) {
    for (int64_t x = x0; x <= x1; ++x) {
      const QRectF cell(toWidget(s.rect, QPointF(static_cast<double>(x), static_cast<double>(y))),
                        QSizeF(zoom_, zoom_));
      // A cell belongs to the pane its centre is in (a wipe's seam cuts no number in two), and the label's plate
      // keeps its corner.
      if (!s.clip.contains(cell.center().toPoint()) || cell.intersects(label)) continue;
      p.setClipRect(cell.intersected(s.rect));
      const QRgb bg = pane.display.pixel(std::min(pane.display.width() - 1, static_cast<int>(x) / pane.display_scale),
                                         std::min(pane.display.height() - 1, static_cast<int>(y) / pane.display_scale));
      const bool dark = qGray(bg) < 128;
      for (int c = 0; c < count; ++c) {
        const float value = v.at(x, y, pane.first_channel + c);
        const QRectF line(cell.x(), cell.y() + cell.height() * (c + 0.5) / (count + 1.0), cell.width(),
                          cell.height() / (count + 1.0));
        QColor col = count == 1 ? (dark ? Qt::white : Qt::black) : kChannelColors[c % 3];
        if (!dark) col = col.darker(250);
        p.setPen(col);
        p.drawText(line, Qt::AlignCenter, fittedValueText(static_cast<double>(value), cell.width() - 4, fm));
      }
    }
  }
  p.setClipRect(s.clip);
}

void ImageCanvas::drawRoi(QPainter& p, const Slot& s) const {
  if (!roi_) return;
  const QPointF a = toWidget(s.rect, QPointF(static_cast<double>(roi_->x), static_cast<double>(roi_->y)));
  const QPointF b = toWidget(s.rect, QPointF(static_cast<double>(roi_->x + roi_->width),
                                             static_cast<double>(roi_->y + roi_->height)));
  p.setBrush(Qt::NoBrush);
  p.setPen(QPen(QColor(0, 0, 0, 200), 3));
  p.drawRect(QRectF(a, b));
  p.setPen(QPen(QColor(255, 220, 0), 1, Qt::DashLine));
  p.drawRect(QRectF(a, b));
}

void ImageCanvas::wheelEvent(QWheelEvent* e) {
  const double steps = e->angleDelta().y() / 120.0;
  if (steps != 0) zoomAbout(std::pow(2.0, steps / 4.0), e->position());
  e->accept();
}

void ImageCanvas::mousePressEvent(QMouseEvent* e) {
  drag_last_ = e->position();
  if (e->button() == Qt::LeftButton && layout_ == Layout::Wipe && std::abs(e->position().x() - wipeSplitX()) <= kWipeGrab) {
    drag_ = Drag::Wipe;
  } else if ((e->button() == Qt::LeftButton && (e->modifiers() & Qt::ShiftModifier)) ||
             e->button() == Qt::RightButton) {
    for (const auto& s : paneSlots()) {
      if (!s.clip.contains(e->position().toPoint())) continue;
      drag_ = Drag::Roi;
      roi_anchor_ = toImage(s.rect, e->position());
    }
  } else if (e->button() == Qt::LeftButton || e->button() == Qt::MiddleButton) {
    drag_ = Drag::Pan;
    setCursor(Qt::ClosedHandCursor);
  }
}

void ImageCanvas::mouseMoveEvent(QMouseEvent* e) {
  const QPointF pos = e->position();
  switch (drag_) {
    case Drag::Pan:
      auto_fit_ = false;
      center_ -= (pos - drag_last_) / zoom_;
      clampView();
      update();
      emit viewChanged();
      break;
    case Drag::Wipe: setWipePosition((pos.x() - rect().left()) / std::max(1, rect().width())); break;
    case Drag::Roi:
      for (const auto& s : paneSlots()) {
        if (!s.rect.contains(drag_last_.toPoint())) continue;
        const QPointF img = toImage(s.rect, pos);
        const auto clampx = [&](double v) { return std::clamp(v, 0.0, static_cast<double>(image_size_.width())); };
        const auto clampy = [&](double v) { return std::clamp(v, 0.0, static_cast<double>(image_size_.height())); };
        const int64_t xa = static_cast<int64_t>(std::floor(clampx(std::min(img.x(), roi_anchor_.x()))));
        const int64_t ya = static_cast<int64_t>(std::floor(clampy(std::min(img.y(), roi_anchor_.y()))));
        const int64_t xb = static_cast<int64_t>(std::ceil(clampx(std::max(img.x(), roi_anchor_.x()))));
        const int64_t yb = static_cast<int64_t>(std::ceil(clampy(std::max(img.y(), roi_anchor_.y()))));
        roi_ = Rect{xa, ya, xb - xa, yb - ya};
        update();
        break;
      }
      break;
    case Drag::None:
      if (layout_ == Layout::Wipe)
        setCursor(std::abs(pos.x() - wipeSplitX()) <= kWipeGrab ? Qt::SplitHCursor : Qt::ArrowCursor);
      break;
  }
  if (drag_ != Drag::Roi) drag_last_ = pos;
  mouse_ = pos;
  hovered_pane_ = paneAt(pos);
  emit hovered(pixelAt(pos));
}

void ImageCanvas::mouseReleaseEvent(QMouseEvent*) {
  if (drag_ == Drag::Roi) {
    if (roi_ && roi_->area() < 4) roi_.reset();  // a click, not a drag: clears the ROI
    update();
    emit roiChanged(roi_);
  }
  if (drag_ == Drag::Pan) unsetCursor();
  drag_ = Drag::None;
}

void ImageCanvas::leaveEvent(QEvent*) {
  mouse_.reset();
  hovered_pane_.reset();
  emit hovered(std::nullopt);
}

void ImageCanvas::resizeEvent(QResizeEvent*) {
  if (!fitted_ || auto_fit_) fit();
}

void ImageCanvas::dragEnterEvent(QDragEnterEvent* e) {
  if (e->mimeData()->hasUrls()) e->acceptProposedAction();
}

void ImageCanvas::dropEvent(QDropEvent* e) {
  QStringList files;
  for (const auto& url : e->mimeData()->urls())
    if (url.isLocalFile()) files << url.toLocalFile();
  if (!files.isEmpty()) emit filesDropped(files);
}

}  // namespace residue::ui
