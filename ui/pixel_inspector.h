// PixelInspector: the linear values of every image and AOV under the cursor (noisy colour, denoised,
// reference, albedo, normal, depth, variance, and the heatmap value), as stored: no exposure, no transform.
#pragma once

#include <QLabel>
#include <optional>

namespace residue {
class Image;
}

namespace residue::ui {

class Session;

class PixelInspector : public QLabel {
  Q_OBJECT
 public:
  explicit PixelInspector(QWidget* parent = nullptr);
  // Shows the values at `pixel` (image coordinates), or a hint when there is none.
  void inspect(const Session& session, std::optional<QPoint> pixel, const Image* heatmap, const QString& heatmap_name);
  // The same text as plain lines "name: v0 v1 v2", for tests and the clipboard.
  static QStringList lines(const Session& session, QPoint pixel, const Image* heatmap, const QString& heatmap_name);
};

}  // namespace residue::ui
