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

namespace {
// The value at fraction q of the finite values of channel 0..channels-1 (a sample of at most ~64k values).
float percentile(const Image& img, int channels, double q) {
  std::vector<float> v;
  const size_t n = static_cast<size_t>(img.width() * img.height());
  const size_t stride = std::max<size_t>(1, n / 65536);
  for (size_t i = 0; i < n; i += stride)
    for (int c = 0; c < channels; ++c)
      if (const float x = img.data()[i * static_cast<size_t>(img.channels()) + static_cast<size_t>(c)]; std::isfinite(x))
        v.push_back(x);
  if (v.empty()) return 0.0f;
  const auto k = static_cast<size_t>(q * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}
}  // namespace

Image data_aov_for_display(const Image& aov, AovRole role, int step) {
  const int channels = std::min(3, aov.channels());
  Image data = subsample(aov, step, channels);
  float* d = data.data();
  const size_t n = data.size();
  switch (role) {
    case AovRole::Normal:
      for (size_t i = 0; i < n; ++i) d[i] = 0.5f * d[i] + 0.5f;
      break;
    case AovRole::Depth: {
      // Near is bright, far dark, over the 1st to 99th percentile: a far background or one stray hit no
      // longer squeezes the room into one grey.
      const float lo = percentile(aov, 1, 0.01), hi = percentile(aov, 1, 0.99);
      const float scale = hi > lo ? 1.0f / (hi - lo) : 1.0f;
      for (size_t i = 0; i < n; ++i)
        d[i] = std::isfinite(d[i]) ? std::clamp(1.0f - (d[i] - lo) * scale, 0.0f, 1.0f) : d[i];
      break;
    }
    case AovRole::Motion: {
      // The motion to the previous frame as colour: red right, green down, mid-grey still, scaled so that the
      // 99th percentile of the displacement's length reaches the edge of the range.
      std::vector<float> lengths;
      for (int64_t y = 0; y < aov.height(); y += step)
        for (int64_t x = 0; x < aov.width(); x += step) lengths.push_back(std::hypot(aov.at(x, y, 0), aov.at(x, y, 1)));
      std::nth_element(lengths.begin(), lengths.begin() + static_cast<std::ptrdiff_t>(lengths.size() * 99 / 100), lengths.end());
      const float hi = lengths.empty() ? 0.0f : lengths[lengths.size() * 99 / 100];
      const float scale = hi > 0 ? 0.5f / hi : 0.0f;
      for (size_t i = 0; i + 2 < n; i += 3) {
        d[i] = std::clamp(0.5f + d[i] * scale, 0.0f, 1.0f);
        d[i + 1] = std::clamp(0.5f + d[i + 1] * scale, 0.0f, 1.0f);
        d[i + 2] = 0.5f;
      }
      break;
    }
    case AovRole::Variance: {
      // Variance spans decades and is mostly tiny: the standard deviation over its 99th percentile.
      for (size_t i = 0; i < n; ++i) d[i] = std::sqrt(std::max(0.0f, d[i]));
      const float hi = std::sqrt(std::max(0.0f, percentile(aov, channels, 0.99)));
      const float scale = hi > 0 ? 1.0f / hi : 1.0f;
      for (size_t i = 0; i < n; ++i) d[i] = std::isfinite(d[i]) ? std::min(1.0f, d[i] * scale) : d[i];
      break;
    }
    default: break;
  }
  return data;
}

Image scalar_layer_for_display(const Image& layer, int step) {
  Image data = subsample(layer, step, 1);
  float* d = data.data();
  const size_t n = data.size();
  bool unit = true;
  for (size_t i = 0; i < n && unit; ++i) unit = !std::isfinite(d[i]) || (d[i] >= 0.0f && d[i] <= 1.0f);
  if (unit) return data;
  const float lo = percentile(layer, 1, 0.01), hi = percentile(layer, 1, 0.99);
  const float scale = hi > lo ? 1.0f / (hi - lo) : 1.0f;
  for (size_t i = 0; i < n; ++i) d[i] = std::isfinite(d[i]) ? std::clamp((d[i] - lo) * scale, 0.0f, 1.0f) : d[i];
  return data;
}

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
          if (in.layer) {
            pane.label = QStringLiteral("Noisy: %1").arg(in.layer_name);
            pane.values = in.layer;
            pane.channel_count = std::min(3, in.layer->channels());
            if (pane.channel_count == 1) {
              const Image data = scalar_layer_for_display(*in.layer, step);
              pane.display = in.display->render(data, 0, 1, data.bounds(), in.settings, Encoding::Data);
            } else {  // a light pass, a colour: through the exposure and the view, as the render is
              pane.display = renderColor(in, *in.layer, pane.channel_count, step);
            }
            break;
          }
          pane.label = in.aov == AovRole::Color ? QStringLiteral("Noisy")
                                                : QStringLiteral("Noisy: %1").arg(display_name(in.aov));
          if (!in.noisy) break;
          pane.values = std::shared_ptr<const Image>(in.stack, in.noisy);
          pane.channel_count = std::min(3, in.noisy->channels());
          if (in.aov == AovRole::Normal || in.aov == AovRole::Depth || in.aov == AovRole::Variance ||
              in.aov == AovRole::Motion) {
            const Image data = data_aov_for_display(*in.noisy, in.aov, step);
            pane.display = in.display->render(data, 0, pane.channel_count, data.bounds(), in.settings, Encoding::Data);
          } else {
            pane.display = renderColor(in, *in.noisy, pane.channel_count, step);
          }
          break;
        }
        case Source::Denoised:
          pane.label = in.a_name.isEmpty() ? QStringLiteral("A: denoised") : QStringLiteral("A: %1").arg(in.a_name);
          pane.placeholder = QStringLiteral("Not denoised yet:\npick a model and press Denoise (Ctrl+D),\n"
                                            "or add a result (File > Add Result)");
          pane.values = in.denoised;
          if (in.denoised) pane.display = renderColor(in, *in.denoised, 3, step);
          break;
        case Source::Compare:
          pane.label = QStringLiteral("B: %1").arg(in.b_name);
          pane.values = in.compare;
          if (in.compare) pane.display = renderColor(in, *in.compare, 3, step);
          break;
        case Source::Reference:
          pane.label = QStringLiteral("Reference");
          pane.values = in.reference;
          if (in.reference) pane.display = renderColor(in, *in.reference, 3, step);
          break;
        case Source::Heatmap:
          pane.label = in.heat_title;
          pane.placeholder = in.heat_placeholder;
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
