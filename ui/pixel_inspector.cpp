#include "ui/pixel_inspector.h"

#include <QFontDatabase>

#include "ui/session.h"

namespace residue::ui {

PixelInspector::PixelInspector(QWidget* parent) : QLabel(parent) {
  setObjectName("pixelInspector");
  setFont(QFontDatabase::systemFont(QFontDatabase::FixedFont));
  setAlignment(Qt::AlignTop | Qt::AlignLeft);
  setTextInteractionFlags(Qt::TextSelectableByMouse);
  setMinimumWidth(260);
  setText(tr("Move the cursor over the image"));
}

QStringList PixelInspector::lines(const Session& session, QPoint pixel, const Image* heatmap,
                                  const QString& heatmap_name) {
  QStringList out;
  out << QString("pixel: %1, %2").arg(pixel.x()).arg(pixel.y());
  const auto add = [&](const QString& name, const Image* img, int count) {
    if (!img || pixel.x() >= img->width() || pixel.y() >= img->height()) return;
    QStringList values;
    for (int c = 0; c < std::min(count, img->channels()); ++c)
      values << QString::number(static_cast<double>(img->at(pixel.x(), pixel.y(), c)), 'g', 6);
    out << QString("%1: %2").arg(name, values.join(' '));
  };
  add("noisy", session.image(Source::Noisy, AovRole::Color), 3);
  // Every result by its name, A and B marked: A as shown (at its strength), the others as they are.
  for (const Result& r : session.results()) {
    const bool is_a = r.id == session.a(), is_b = r.id == session.b();
    const Image* img = is_a ? session.denoised() : r.image.get();
    add(QString("%1%2").arg(is_a ? "A " : is_b ? "B " : "", session.resultName(r.id)), img, 3);
  }
  add("reference", session.image(Source::Reference, AovRole::Color), 3);
  add("albedo", session.image(Source::Noisy, AovRole::Albedo), 3);
  add("normal", session.image(Source::Noisy, AovRole::Normal), 3);
  add("depth", session.image(Source::Noisy, AovRole::Depth), 1);
  add("variance", session.image(Source::Noisy, AovRole::Variance), 3);
  add("motion (to previous, to next; px)", session.image(Source::Noisy, AovRole::Motion), 4);
  add(heatmap_name.isEmpty() ? QStringLiteral("heatmap") : heatmap_name, heatmap, 1);
  return out;
}

void PixelInspector::inspect(const Session& session, std::optional<QPoint> pixel, const Image* heatmap,
                             const QString& heatmap_name) {
  if (!pixel || !session.hasStack()) {
    setText(tr("Move the cursor over the image"));
    return;
  }
  setText(lines(session, *pixel, heatmap, heatmap_name).join('\n'));
}

}  // namespace residue::ui
