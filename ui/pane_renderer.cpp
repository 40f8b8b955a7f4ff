#include "ui/pane_renderer.h"

#include <algorithm>
#include <cmath>

namespace residue::ui {

namespace {
// Every step-th pixel of the first `channels` channels (a copy; step 1 copies too, so callers can remap it).
Image subsample(const Image& src, int step, int channels) {
  const int64_t w = (src.width() + step - 1) / step, h = (src.height() + step - 1) / step;
  Image out(w, h, channels);
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x)
      for (int c = 0; c < channels; ++c) out.at(x, y, c) = src.at(x * step, y * step, c);
  return out;
}

QImage renderColor(const PaneInputs& in, const Image& img, int channels, int step) {
  if (step == 1) return in.display->render(img, 0, channels, img.bounds(), in.settings, Encoding::SceneLinear);
  const Image small = subsample(img, step, channels);
  return in.display->render(small, 0, channels, small.bounds(), in.settings, Encoding::SceneLinear);
}
}  // namespace

int preview_step(int64_t width, int64_t height, int64_t target) {
  return static_cast<int>(std::max<int64_t>(1, std::max(width, height) / target));
}

std::vector<Pane> render_panes(const PaneInputs& in, int step) {
  std::vector<Pane> panes;
  for (Source s : in.sources) {
    Pane pane;
    pane.display_scale = step;
    try {
      switch (s) {
        case Source::Noisy: {
          pane.label = in.aov == AovRole::Color ? QStringLiteral("Noisy")
                                                : QStringLiteral("Noisy: %1").arg(display_name(in.aov));
          if (!in.noisy) break;
          pane.values = std::shared_ptr<const Image>(in.stack, in.noisy);
          pane.channel_count = std::min(3, in.noisy->channels());
          if (in.aov == AovRole::Normal || in.aov == AovRole::Depth) {
            // Data AOVs are shown as data: normals as 0.5 n + 0.5, depth divided by its largest hit.
            Image data = subsample(*in.noisy, step, pane.channel_count);
            float scale = 1.0f;
            if (in.aov == AovRole::Depth) {
              float hi = 0.0f;
              for (size_t i = 0; i < in.noisy->size(); ++i)
                if (std::isfinite(in.noisy->data()[i])) hi = std::max(hi, in.noisy->data()[i]);
              scale = hi > 0 ? 1.0f / hi : 1.0f;
            }
            for (size_t i = 0; i < data.size(); ++i)
              data.data()[i] = in.aov == AovRole::Normal ? 0.5f * data.data()[i] + 0.5f : data.data()[i] * scale;
            pane.display = in.display->render(data, 0, pane.channel_count, data.bounds(), in.settings, Encoding::Data);
          } else {
            pane.display = renderColor(in, *in.noisy, pane.channel_count, step);
          }
          break;
        }
        case Source::Denoised:
          pane.label = in.model.isEmpty() ? QStringLiteral("Denoised") : QStringLiteral("Denoised: %1").arg(in.model);
          pane.placeholder = QStringLiteral("Not denoised yet:\npick a model and press Denoise (Ctrl+D)");
          pane.values = in.denoised;
          if (in.denoised) pane.display = renderColor(in, *in.denoised, 3, step);
          break;
        case Source::Reference:
          pane.label = QStringLiteral("Reference");
          pane.values = in.reference;
          if (in.reference) pane.display = renderColor(in, *in.reference, 3, step);
          break;
        case Source::Heatmap:
          pane.label = in.heat_title;
          pane.placeholder = QStringLiteral("%1\n(needs a denoised image)").arg(in.heat_title);
          pane.display = in.heat_image;
          pane.display_scale = 1;
          pane.values = in.heat_map;
          pane.channel_count = 1;
          break;
      }
    } catch (const std::exception& e) {
      pane.label += QStringLiteral(" (%1)").arg(QString::fromStdString(e.what()));
      pane.display = QImage();
    }
    panes.push_back(std::move(pane));
  }
  return panes;
}

}  // namespace residue::ui
