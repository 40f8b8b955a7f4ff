// The viewer's display maths, in one place (as in tev): exposure and offset, then an OpenColorIO display/view
// transform, from linear float pixels to an 8-bit QImage, plus the same maths for one pixel (the pixel
// inspector and the tests). OCIO stays behind a pimpl so that widgets do not include its headers.
#pragma once

#include <array>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <QImage>

#include "core/image/image.h"

namespace residue::ui {

// Rec. 709's luminance Y of scene-linear RGB: the one weighting the display maths uses (channel isolation, false
// colour, the image histogram).
inline float rec709_luminance(float r, float g, float b) { return 0.2126f * r + 0.7152f * g + 0.0722f * b; }

// One channel shown alone, as grey through the same view (tev's channel isolation), or all three. Luminance is
// Rec. 709's Y of the scene-linear values.
enum class DisplayChannel { RGB, R, G, B, Luminance };
const char* to_string(DisplayChannel c);  // "rgb", "r", "g", "b", "luminance"
std::optional<DisplayChannel> display_channel_from_string(const std::string& name);

struct DisplaySettings {
  double exposure = 0.0;  // stops: values are multiplied by 2^exposure
  double offset = 0.0;    // added after the exposure
  std::string display;    // OCIO display; empty = the config's default
  std::string view;       // OCIO view; empty = the display's default
  DisplayChannel channel = DisplayChannel::RGB;  // taken after the exposure, before the view
  double gamma = 1.0;     // after the view, display values v become v^(1/gamma): > 1 opens the shadows (tev's)
  // render() only: pixels the view clips drawn in warning colours instead, kClipHigh where a channel reaches 1,
  // kClipLow where all are at or below 0 (before the gamma).
  bool clipping = false;
  // Instead of the view, false colour: exposed scene-linear luminance in stops about mid grey (0.18), log2(Y/0.18)
  // over [-kFalseColourStops, +kFalseColourStops], through the turbo colormap (mid grey in its middle). Scene-linear
  // images only; apply() gives the same colour.
  bool false_colour = false;
};

inline constexpr double kFalseColourStops = 6.5;

inline constexpr uint32_t kClipHigh = 0xffff3030u;  // ARGB
inline constexpr uint32_t kClipLow = 0xff3050ffu;

// How a buffer's values are meant: radiance/albedo go through OCIO; Data (normals remapped to [0,1], depth
// normalised, heatmaps already in display colour) is only exposure/offset + clamp, no transform.
enum class Encoding { SceneLinear, Data };

class DisplayTransform {
 public:
  // $OCIO when set and it loads; else the shipped fallback config (find_resource("ocio/config.ocio")).
  // Never throws: if nothing loads, an internal fallback (the sRGB OETF, no OCIO) is used and note() says why.
  static std::shared_ptr<const DisplayTransform> load_default();
  // Throws residue::Error(Input) naming the file and OCIO's message. The default display/view's processor
  // is built here, so a config whose LUTs are missing fails now rather than on the first frame.
  static std::shared_ptr<const DisplayTransform> load(const std::filesystem::path& config);
  // The internal fallback without OCIO: display "sRGB" with the shipped config's views ("Filmic (Hable)",
  // the default, = residue::tonemap_filmic_srgb; "Standard" = residue::srgb_oetf; "Raw" = clamp only).
  static std::shared_ptr<const DisplayTransform> builtin(std::string note = {});

  ~DisplayTransform();
  DisplayTransform(const DisplayTransform&) = delete;
  DisplayTransform& operator=(const DisplayTransform&) = delete;

  std::string source() const;  // config path, or "built-in sRGB (no OCIO config)"
  std::string note() const;    // why this config (e.g. "$OCIO=/x failed: ...; using the shipped fallback")
  bool uses_ocio() const;      // false for the built-in fallback
  std::vector<std::string> displays() const;
  std::vector<std::string> views(const std::string& display) const;  // empty for an unknown display
  std::string default_display() const;
  std::string default_view(const std::string& display) const;

  // One pixel: linear RGB -> display RGB in [0,1] (exposure, offset, then OCIO scene_linear -> display/view for
  // SceneLinear; clamp only for Data). NaN/Inf input -> returns {NaN,NaN,NaN} so callers can flag it.
  // Throws residue::Error(Usage) for a display/view the config does not have, Error(Input) when OCIO cannot
  // build that view (e.g. its LUT file is missing).
  std::array<float, 3> apply(std::array<float, 3> linear, const DisplaySettings& settings, Encoding enc) const;

  // `rect` of `image` -> QImage::Format_RGB32 of rect's size, channels [first, first+count): count 1 = grey
  // (replicated to RGB), count 2 = (c0, c1, 0), count >= 3 = the first three. Pixels with a NaN/Inf in those
  // channels are drawn magenta (255,0,255) so they stand out. Parallel (oneTBB parallel_for over rows); safe to
  // call from several threads at once. An empty rect gives a null QImage. Throws residue::Error(Usage) for a
  // rect outside the image or channels out of range, and as apply() for display/view.
  QImage render(const Image& image, int first_channel, int count, const Rect& rect, const DisplaySettings& s,
                Encoding enc) const;

 private:
  struct Impl;
  explicit DisplayTransform(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace residue::ui
