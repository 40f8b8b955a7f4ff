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
  int lines = 0, detail_lines = 0;
  QSize detail;  // the region's size on the sheet: as large as half a cell allows, by a whole factor when enlarged
  for (const auto& p : panels) {
    lines = std::max(lines, static_cast<int>(p.lines.size()));
    detail_lines = std::max(detail_lines, static_cast<int>(p.detail_lines.size()));
    if (!p.detail.isNull() && detail.isEmpty()) {
      const QSize fit = p.detail.size().scaled(std::max(cell_image.width(), 200), std::max(cell_image.height() / 2, 100),
                                              Qt::KeepAspectRatio);
      const int k = fit.width() / std::max(1, p.detail.width());
      detail = k >= 1 ? p.detail.size() * k : fit;
    }
  }
  const int cell_w = std::max({cell_image.width(), detail.width(), 200});
  const int detail_h = detail.isEmpty() ? 0 : 8 + detail.height() + 4 + detail_lines * line;
  const int cell_h = line + 4 + cell_image.height() + 4 + lines * line + detail_h;
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
    if (!panel.region.isEmpty() && !panel.image.isNull()) {  // where the region lies, outlined
      const double sx = double(target.width()) / panel.image.width(), sy = double(target.height()) / panel.image.height();
      const QRectF r(target.x() + panel.region.x() * sx, target.y() + panel.region.y() * sy, panel.region.width() * sx,
                     panel.region.height() * sy);
      p.setPen(QPen(QColor(255, 220, 0), 2));
      p.drawRect(r);
      p.setPen(Qt::black);
    }
    for (int k = 0; k < panel.lines.size(); ++k)
      p.drawText(QRect(x, target.bottom() + 5 + k * line, cell_w, line), Qt::AlignLeft | Qt::AlignVCenter,
                 fm.elidedText(panel.lines[k], Qt::ElideRight, cell_w));
    if (!detail.isEmpty()) {
      const QRect d(x, target.bottom() + 5 + lines * line + 8, detail.width(), detail.height());
      if (panel.detail.isNull()) {
        p.fillRect(d, QColor(230, 230, 230));
      } else {
        p.setRenderHint(QPainter::SmoothPixmapTransform, false);
        p.drawImage(d, panel.detail);
        p.setRenderHint(QPainter::SmoothPixmapTransform);
      }
      for (int k = 0; k < panel.detail_lines.size(); ++k)
        p.drawText(QRect(x, d.bottom() + 5 + k * line, cell_w, line), Qt::AlignLeft | Qt::AlignVCenter,
                   fm.elidedText(panel.detail_lines[k], Qt::ElideRight, cell_w));
    }
  }
  return sheet;
}

}  // namespace residue::ui
