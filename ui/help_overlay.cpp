#include "ui/help_overlay.h"

#include <QEvent>
#include <QFontMetrics>
#include <QPainter>
#include <algorithm>

namespace residue::ui {

HelpOverlay::HelpOverlay(QWidget* parent) : QWidget(parent) {
  setObjectName("helpOverlay");
  if (parent) parent->installEventFilter(this);
  hide();
}

void HelpOverlay::setShortcuts(std::vector<std::pair<QString, QString>> shortcuts) {
  shortcuts_ = std::move(shortcuts);
  update();
}

void HelpOverlay::toggle() {
  if (isVisible()) {
    hide();
    return;
  }
  setGeometry(parentWidget()->rect());
  raise();
  show();
}

HelpOverlay::Plan HelpOverlay::plan() const {
  // The largest font (from 1.1x the widget's down to 7 pt) at which every row fits unshortened, in as many columns
  // as the width allows; at the smallest, descriptions are shortened to their column.
  const int n = static_cast<int>(shortcuts_.size());
  Plan plan;
  for (double pt = font().pointSizeF() * 1.1;; pt -= 0.5) {
    plan.font = font();
    plan.font.setPointSizeF(std::max(7.0, pt));
    const QFontMetrics fm(plan.font);
    plan.line = fm.height() + 4;
    plan.key_width = plan.what_width = 0;
    for (const auto& [k, w] : shortcuts_) {
      plan.key_width = std::max(plan.key_width, fm.horizontalAdvance(k));
      plan.what_width = std::max(plan.what_width, fm.horizontalAdvance(w));
    }
    const int room_w = width() - 2 * kMargin, room_h = height() - 2 * kMargin;
    const int fit = std::clamp(room_h / plan.line - 2, 1, std::max(1, n));  // rows under the title
    plan.columns = (n + fit - 1) / std::max(1, fit);
    plan.rows = (n + plan.columns - 1) / std::max(1, plan.columns);  // columns filled evenly
    const int full = plan.key_width + 24 + plan.what_width + 24;
    plan.column_width = std::min(full, room_w / std::max(1, plan.columns));
    plan.shortened = plan.column_width < full;
    if (!plan.shortened || pt <= 7.0) return plan;
  }
}

void HelpOverlay::paintEvent(QPaintEvent*) {
  QPainter p(this);
  p.fillRect(rect(), QColor(0, 0, 0, 120));
  const Plan pl = plan();
  p.setFont(pl.font);
  const QFontMetrics fm(pl.font);
  const int n = static_cast<int>(shortcuts_.size());
  // An opaque plate under the text, so that nothing of the canvas (its pane labels) reads through it.
  const int w = pl.columns * pl.column_width + 24, h = pl.line * (pl.rows + 2) + 16;
  const QRect plate(std::max(kMargin / 2, (width() - w) / 2), std::max(kMargin / 2, (height() - h) / 2), w, h);
  p.fillRect(plate, QColor(24, 24, 24, 245));
  const int x0 = plate.left() + 12;
  int y0 = plate.top() + 8 + fm.ascent();
  p.setPen(Qt::white);
  p.drawText(x0, y0, tr("Keyboard shortcuts (? or Esc to close)"));
  y0 += 2 * pl.line;
  for (int i = 0; i < n; ++i) {
    const auto& [keys, what] = shortcuts_[static_cast<size_t>(i)];
    const int x = x0 + (i / pl.rows) * pl.column_width, y = y0 + (i % pl.rows) * pl.line;
    p.setPen(QColor(255, 220, 120));
    p.drawText(x, y, keys);
    p.setPen(Qt::white);
    p.drawText(x + pl.key_width + 24, y, fm.elidedText(what, Qt::ElideRight, pl.column_width - pl.key_width - 24));
  }
}

bool HelpOverlay::eventFilter(QObject* watched, QEvent* event) {
  if (watched == parentWidget() && event->type() == QEvent::Resize) setGeometry(parentWidget()->rect());
  return false;
}

void HelpOverlay::mousePressEvent(QMouseEvent*) { hide(); }

}  // namespace residue::ui
