#include "ui/help_overlay.h"

#include <QPainter>

namespace residue::ui {

HelpOverlay::HelpOverlay(std::vector<std::pair<QString, QString>> shortcuts, QWidget* parent)
    : QWidget(parent), shortcuts_(std::move(shortcuts)) {
  setObjectName("helpOverlay");
  hide();
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
  int key_width = 0;
  for (const auto& [k, _] : shortcuts_) key_width = std::max(key_width, fm.horizontalAdvance(k));
  const int total_h = line * (static_cast<int>(shortcuts_.size()) + 2);
  int y = std::max(10, (height() - total_h) / 2);
  const int x = std::max(10, width() / 2 - key_width - 20);
  p.setPen(Qt::white);
  p.drawText(x, y, tr("Keyboard shortcuts (? or Esc to close)"));
  y += 2 * line;
  for (const auto& [keys, what] : shortcuts_) {
    p.setPen(QColor(255, 220, 120));
    p.drawText(x, y, keys);
    p.setPen(Qt::white);
    p.drawText(x + key_width + 24, y, what);
    y += line;
  }
}

void HelpOverlay::mousePressEvent(QMouseEvent*) { hide(); }

}  // namespace residue::ui
