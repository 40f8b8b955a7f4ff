#include "ui/comparison_sheet.h"

#include <QObject>
#include <QPainter>
#include <algorithm>
#include <cmath>

namespace residue::ui {

QImage comparison_sheet(const std::vector<SheetPanel>& panels, const SheetOptions& options) {
  if (panels.empty()) return {};
  QSize image_size;
  for (const auto& p : panels) image_size = image_size.expandedTo(p.image.size());
  if (image_size.isEmpty()) return {};
  QSize cell_image = image_size;
  if (options.max_edge > 0 && std::max(image_size.width(), image_size.height()) > options.max_edge)
    cell_image = image_size.scaled(options.max_edge, options.max_edge, Qt::KeepAspectRatio);

  const int n = static_cast<int>(panels.size());
  int columns = std::min(n, std::max(1, options.max_columns));
  while (columns > 1 && (n + columns - 2) / (columns - 1) == (n + columns - 1) / columns) --columns;  // fewest
  const int rows = (n + columns - 1) / columns;

  QFont font;
  font.setPixelSize(14);
  const QFontMetrics fm(font);
  const int line = fm.height(), margin = 16, gap = 12;
  int lines = 0;
  for (const auto& p : panels) lines = std::max(lines, static_cast<int>(p.lines.size()));
  const int cell_w = std::max(cell_image.width(), 200);
  const int cell_h = line + 4 + cell_image.height() + 4 + lines * line;
  const int title_h = options.title.isEmpty() ? 0 : line + gap;
  QImage sheet(2 * margin + columns * cell_w + (columns - 1) * gap,
               2 * margin + title_h + rows * cell_h + (rows - 1) * gap, QImage::Format_RGB32);
  sheet.fill(Qt::white);
  QPainter p(&sheet);
  p.setFont(font);
  p.setPen(Qt::black);
  p.setRenderHint(QPainter::SmoothPixmapTransform);
  if (!options.title.isEmpty())
    p.drawText(QRect(margin, margin, sheet.width() - 2 * margin, line), Qt::AlignLeft | Qt::AlignVCenter,
               fm.elidedText(options.title, Qt::ElideMiddle, sheet.width() - 2 * margin));
  for (int i = 0; i < n; ++i) {
    const auto& panel = panels[static_cast<size_t>(i)];
    const int x = margin + (i % columns) * (cell_w + gap);
    const int y = margin + title_h + (i / columns) * (cell_h + gap);
    QFont bold = font;
    bold.setBold(true);
    p.setFont(bold);
    p.drawText(QRect(x, y, cell_w, line), Qt::AlignLeft | Qt::AlignVCenter,
               QFontMetrics(bold).elidedText(panel.label, Qt::ElideMiddle, cell_w));
    p.setFont(font);
    const QRect target(x, y + line + 4, cell_image.width(), cell_image.height());
    if (panel.image.isNull()) {
      p.fillRect(target, QColor(230, 230, 230));
      p.drawText(target, Qt::AlignCenter, QObject::tr("(no image)"));
    } else {
      p.drawImage(target, panel.image);
    }
    for (int k = 0; k < panel.lines.size(); ++k)
      p.drawText(QRect(x, target.bottom() + 5 + k * line, cell_w, line), Qt::AlignLeft | Qt::AlignVCenter,
                 fm.elidedText(panel.lines[k], Qt::ElideRight, cell_w));
  }
  return sheet;
}

}  // namespace residue::ui
