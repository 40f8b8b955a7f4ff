#include "ui/help_overlay.h"

#include <QEvent>
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

void HelpOverlay::paintEvent(QPaintEvent*) {
  QPainter p(this);
  p.fillRect(rect(), QColor(0, 0, 0, 190));
  QFont f = font();
  f.setPointSizeF(f.pointSizeF() * 1.1);
  p.setFont(f);
  const QFontMetrics fm(f);
  const int line = fm.height() + 4;
  int key_width = 0, what_width = 0;
  for (const auto& [k, w] : shortcuts_) {
    key_width = std::max(key_width, fm.horizontalAdvance(k));
    what_width = std::max(what_width, fm.horizontalAdvance(w));
  }
  // As many rows as fit the height, in as many columns as that takes; descriptions shortened to the width.
  const int n = static_cast<int>(shortcuts_.size());
  const int fit = std::clamp((height() - 20) / line - 2, 1, std::max(1, n));
  const int columns = (n + fit - 1) / fit;
  const int rows = (n + columns - 1) / columns;  // the columns filled evenly, not one full and one nearly empty
  const int column_width = std::min(key_width + 24 + what_width + 32, (width() - 20) / columns);
  const int x0 = std::max(10, (width() - columns * column_width) / 2);
  int y0 = std::max(10 + fm.ascent(), (height() - line * (std::min(rows, n) + 2)) / 2);
  p.setPen(Qt::white);
  p.drawText(x0, y0, tr("Keyboard shortcuts (? or Esc to close)"));
  y0 += 2 * line;
  for (int i = 0; i < n; ++i) {
    const auto& [keys, what] = shortcuts_[static_cast<size_t>(i)];
    const int x = x0 + (i / rows) * column_width, y = y0 + (i % rows) * line;
    p.setPen(QColor(255, 220, 120));
    p.drawText(x, y, keys);
    p.setPen(Qt::white);
    p.drawText(x + key_width + 24, y, fm.elidedText(what, Qt::ElideRight, column_width - key_width - 32));
  }
}

bool HelpOverlay::eventFilter(QObject* watched, QEvent* event) {
  if (watched == parentWidget() && event->type() == QEvent::Resize) setGeometry(parentWidget()->rect());
  return false;
}

void HelpOverlay::mousePressEvent(QMouseEvent*) { hide(); }

}  // namespace residue::ui
