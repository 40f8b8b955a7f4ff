// oneTBB before Qt: Qt defines `emit` as a macro, and TBB has a member function of that name.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "ui/display_transform.h"

#include <algorithm>
#include <bit>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <map>
#include <mutex>
#include <utility>

#include <OpenColorIO/OpenColorIO.h>

#include "core/image/colormap.h"
#include "core/metrics/tonemap.h"
#include "core/util/error.h"
#include "core/util/resources.h"

namespace OCIO = OCIO_NAMESPACE;

namespace residue::ui {
namespace {

constexpr const char* kBuiltinSource = "built-in sRGB (no OCIO config)";
constexpr const char* kBuiltinDisplay = "sRGB";
// Same names and order as resources/ocio/config.ocio, so a saved view survives falling back.
enum class BuiltinView { Filmic, Standard, Raw };
constexpr std::array<std::pair<const char*, BuiltinView>, 3> kBuiltinViews{{
    {"Filmic (Hable)", BuiltinView::Filmic},
    {"Standard", BuiltinView::Standard},
    {"Raw", BuiltinView::Raw},
}};

// Clamp to [0,1] on the bit pattern: non-negative floats order like their bits as int32 and negative ones are
// negative int32s, so two integer clamps do it, which the compiler vectorises (float compares it keeps as
// branches, mispredicted on noisy renders: that loop ran at half speed). A NaN that OCIO makes from a finite
// input (never from the shipped config) gives 0 or 1 by its sign bit, not NaN.
inline float clamp01(float v) {
  const auto bits = std::bit_cast<int32_t>(v);
  return std::bit_cast<float>(std::min(std::max(bits, int32_t{0}), std::bit_cast<int32_t>(1.0f)));
}

// Exposure/offset on a finite value; clamped to the float range so that a huge value times 2^exposure stays
// a number (OCIO and the 8-bit conversion then saturate it) instead of becoming Inf.
inline float expose(float v, float scale, float offset) {
  return std::min(FLT_MAX, std::max(-FLT_MAX, v * scale + offset));
}

// 2^exposure as a float that cannot be Inf (0 * Inf would be NaN).
inline float exposure_scale(double exposure) {
  return static_cast<float>(std::min(std::exp2(exposure), static_cast<double>(FLT_MAX)));
}

// Any float -> 8-bit code of clamp01(v), rounded to nearest.
inline uint8_t to_code(float v) { return static_cast<uint8_t>(static_cast<int32_t>(clamp01(v) * 255.0f + 0.5f)); }

constexpr uint32_t kMagenta = 0xffff00ffu;

// One row of `width` pixels, `channels` apart, -> exposed RGB triplets; `Shown` channels: 1 = grey, 2 = (c0, c1,
// 0), 3 = RGB. A pixel with a non-finite shown channel is marked bad and given 0 so OCIO never sees it.
// A template so that the channel choice is not a branch per pixel.
template <int Shown>
void expose_row(const float* src, int channels, int64_t width, float scale, float offset, float* rgb,
                uint8_t* bad) {
  for (int64_t x = 0; x < width; ++x, src += channels, rgb += 3) {
    const float r = src[0];
    const float g = Shown == 1 ? r : src[1];
    const float b = Shown == 1 ? r : (Shown == 2 ? 0.0f : src[2]);
    const bool finite = std::isfinite(r) & std::isfinite(g) & std::isfinite(b);
    bad[x] = finite ? 0 : 1;
    const float er = expose(r, scale, offset), eg = expose(g, scale, offset), eb = expose(b, scale, offset);
    rgb[0] = finite ? er : 0.0f;
    rgb[1] = finite ? eg : 0.0f;
    rgb[2] = finite ? eb : 0.0f;
  }
}

// A pixel's flag in render(): fine, not finite (magenta), or clipped by the view (clipping warnings).
constexpr uint8_t kBad = 1, kHigh = 2, kLow = 3;

// Flags the pixels the view clips (display values, before quantisation): a channel at or above 1, or all at or
// below 0. A pixel already flagged as not finite stays so.
void clip_row(const float* rgb, int64_t n, uint8_t* flags) {
  for (int64_t x = 0; x < n; ++x, rgb += 3) {
    if (flags[x]) continue;
    if (rgb[0] >= 1.0f || rgb[1] >= 1.0f || rgb[2] >= 1.0f) flags[x] = kHigh;
    else if (rgb[0] <= 0.0f && rgb[1] <= 0.0f && rgb[2] <= 0.0f) flags[x] = kLow;
  }
}

// False colour: each exposed triplet replaced by turbo's colour for its luminance's stops about mid grey, as
// display values (sRGB-encoded, so the view is skipped).
void false_colour_row(float* rgb, int64_t n) {
  for (int64_t x = 0; x < n; ++x, rgb += 3) {
    const double y = rec709_luminance(rgb[0], rgb[1], rgb[2]);
    const double stops = y > 0 ? std::log2(y / 0.18) : -kFalseColourStops;
    const auto c = colormap_lookup(Colormap::Turbo, (stops + kFalseColourStops) / (2 * kFalseColourStops));
    for (int k = 0; k < 3; ++k) rgb[k] = static_cast<float>(c[static_cast<size_t>(k)]) / 255.0f;
  }
}

// The channel shown alone, as grey: in place on `n` RGB triplets.
void isolate_row(float* rgb, int64_t n, DisplayChannel c) {
  if (c == DisplayChannel::RGB) return;
  for (int64_t x = 0; x < n; ++x, rgb += 3) {
    const float v = c == DisplayChannel::R   ? rgb[0]
                    : c == DisplayChannel::G ? rgb[1]
                    : c == DisplayChannel::B ? rgb[2]
                                             : rec709_luminance(rgb[0], rgb[1], rgb[2]);
    rgb[0] = rgb[1] = rgb[2] = v;
  }
}

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "\"" : ", \"") + n + "\"";
  return out.empty() ? "none" : out;
}

}  // namespace

// How one (display, view) turns exposed linear RGB into display RGB: an OCIO CPU processor, or a built-in curve.
struct Pipeline {
  OCIO::ConstCPUProcessorRcPtr ocio;  // null for the built-in fallback
  BuiltinView builtin = BuiltinView::Filmic;

  // `rgb` holds `n` interleaved RGB triplets; transformed in place (not yet clamped).
  void apply_row(float* rgb, int64_t n) const {
    if (n <= 0) return;
    if (ocio) {
      OCIO::PackedImageDesc desc(rgb, static_cast<long>(n), 1, 3);
      ocio->apply(desc);
      return;
    }
    const int64_t values = n * 3;
    switch (builtin) {
      case BuiltinView::Filmic:
        for (int64_t i = 0; i < values; ++i) rgb[i] = tonemap_filmic_srgb(rgb[i]);
        break;
      case BuiltinView::Standard:
        for (int64_t i = 0; i < values; ++i) rgb[i] = srgb_oetf(rgb[i]);
        break;
      case BuiltinView::Raw:
        break;
    }
  }
};

struct DisplayTransform::Impl {
  OCIO::ConstConfigRcPtr config;  // null: built-in fallback
  std::string source;
  std::string note;

  // Processors are built on first use per (display, view) as the caller spelled them (empty = default), so
  // the common case is one map lookup. render() may run on several threads at once, hence the mutex.
  mutable std::mutex mutex;
  mutable std::map<std::pair<std::string, std::string>, Pipeline> cache;

  std::vector<std::string> displays() const {
    if (!config) return {kBuiltinDisplay};
    std::vector<std::string> out;
    for (int i = 0; i < config->getNumDisplays(); ++i) out.emplace_back(config->getDisplay(i));
    return out;
  }

  std::vector<std::string> views(const std::string& display) const {
    std::vector<std::string> out;
    if (!config) {
      if (display == kBuiltinDisplay)
        for (const auto& v : kBuiltinViews) out.emplace_back(v.first);
      return out;
    }
    for (int i = 0; i < config->getNumViews(display.c_str()); ++i) out.emplace_back(config->getView(display.c_str(), i));
    return out;
  }

  std::string default_display() const { return config ? config->getDefaultDisplay() : kBuiltinDisplay; }

  std::string default_view(const std::string& display) const {
    if (!config) return display == kBuiltinDisplay ? kBuiltinViews[0].first : "";
    return config->getDefaultView(display.c_str());
  }

  Pipeline build(const std::string& display_in, const std::string& view_in) const {
    const std::string display = display_in.empty() ? default_display() : display_in;
    const auto all_displays = displays();
    if (std::find(all_displays.begin(), all_displays.end(), display) == all_displays.end())
      throw Error(ErrorKind::Usage, "display \"" + display + "\" is not in " + source + " (it has " +
                                        joined(all_displays) + ")");
    const std::string view = view_in.empty() ? default_view(display) : view_in;
    const auto all_views = views(display);
    if (std::find(all_views.begin(), all_views.end(), view) == all_views.end())
      throw Error(ErrorKind::Usage, "view \"" + view + "\" is not a view of display \"" + display + "\" in " +
                                        source + " (it has " + joined(all_views) + ")");

    Pipeline p;
    if (!config) {
      for (const auto& v : kBuiltinViews)
        if (view == v.first) p.builtin = v.second;
      return p;
    }
    try {
      auto t = OCIO::DisplayViewTransform::Create();
      // Renders are scene-linear; a config without that role falls back to its default colour space.
      t->setSrc(config->hasRole(OCIO::ROLE_SCENE_LINEAR) ? OCIO::ROLE_SCENE_LINEAR : OCIO::ROLE_DEFAULT);
      t->setDisplay(display.c_str());
      t->setView(view.c_str());
      p.ocio = config->getProcessor(t)->getOptimizedCPUProcessor(OCIO::BIT_DEPTH_F32, OCIO::BIT_DEPTH_F32,
                                                                 OCIO::OPTIMIZATION_DEFAULT);
      // A data view (Raw) is a no-op, but OCIO would still copy every row through its scratch buffers.
      if (p.ocio->isNoOp()) {
        p.ocio = nullptr;
        p.builtin = BuiltinView::Raw;
      }
    } catch (const OCIO::Exception& e) {
      throw Error(ErrorKind::Input, "OCIO config " + source + ": cannot build display \"" + display +
                                        "\", view \"" + view + "\": " + e.what());
    }
    return p;
  }

  Pipeline pipeline(const DisplaySettings& s) const {
    std::lock_guard lock(mutex);
    auto key = std::make_pair(s.display, s.view);
    if (auto it = cache.find(key); it != cache.end()) return it->second;
    Pipeline p = build(s.display, s.view);
    cache.emplace(std::move(key), p);
    return p;
  }
};

DisplayTransform::DisplayTransform(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
DisplayTransform::~DisplayTransform() = default;

std::shared_ptr<const DisplayTransform> DisplayTransform::builtin(std::string note) {
  auto impl = std::make_unique<Impl>();
  impl->source = kBuiltinSource;
  impl->note = std::move(note);
  return std::shared_ptr<const DisplayTransform>(new DisplayTransform(std::move(impl)));
}

std::shared_ptr<const DisplayTransform> DisplayTransform::load(const std::filesystem::path& config) {
  auto impl = std::make_unique<Impl>();
  impl->source = config.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(config, ec))
    throw Error(ErrorKind::Input, "OCIO config " + impl->source + ": no such file");
  try {
    impl->config = OCIO::Config::CreateFromFile(impl->source.c_str());
    impl->config->validate();
  } catch (const OCIO::Exception& e) {
    throw Error(ErrorKind::Input, "OCIO config " + impl->source + ": " + e.what());
  }
  if (impl->config->getNumDisplays() == 0)
    throw Error(ErrorKind::Input, "OCIO config " + impl->source + ": defines no display");
  impl->note = "loaded " + impl->source;
  // Build the default view now: a missing LUT or a broken transform should fail the load, not a frame.
  impl->pipeline(DisplaySettings{});
  return std::shared_ptr<const DisplayTransform>(new DisplayTransform(std::move(impl)));
}

std::shared_ptr<const DisplayTransform> DisplayTransform::load_default() {
  std::string note;
  if (const char* env = std::getenv("OCIO"); env && *env) {
    try {
      auto t = load(env);
      t->impl_->note = std::string("from $OCIO=") + env;
      return t;
    } catch (const std::exception& e) {
      note = std::string("$OCIO=") + env + " failed: " + e.what() + "; ";
    }
  } else {
    note = "$OCIO not set; ";
  }
  if (const auto shipped = find_resource("ocio/config.ocio")) {
    try {
      auto t = load(*shipped);
      t->impl_->note = note + "using the shipped fallback";
      return t;
    } catch (const std::exception& e) {
      note += std::string("the shipped fallback failed: ") + e.what() + "; ";
    }
  } else {
    note += "the shipped fallback ocio/config.ocio was not found; ";
  }
  return builtin(note + "using the built-in sRGB transform");
}

std::string DisplayTransform::source() const { return impl_->source; }
std::string DisplayTransform::note() const { return impl_->note; }
bool DisplayTransform::uses_ocio() const { return impl_->config != nullptr; }
std::vector<std::string> DisplayTransform::displays() const { return impl_->displays(); }
std::vector<std::string> DisplayTransform::views(const std::string& display) const {
  return impl_->views(display);
}
std::string DisplayTransform::default_display() const { return impl_->default_display(); }
std::string DisplayTransform::default_view(const std::string& display) const {
  return impl_->default_view(display);
}

const char* to_string(DisplayChannel c) {
  switch (c) {
    case DisplayChannel::RGB: return "rgb";
    case DisplayChannel::R: return "r";
    case DisplayChannel::G: return "g";
    case DisplayChannel::B: return "b";
    case DisplayChannel::Luminance: return "luminance";
  }
  return "?";
}

std::optional<DisplayChannel> display_channel_from_string(const std::string& name) {
  for (DisplayChannel c : {DisplayChannel::RGB, DisplayChannel::R, DisplayChannel::G, DisplayChannel::B,
                           DisplayChannel::Luminance})
    if (name == to_string(c)) return c;
  return std::nullopt;
}

std::array<float, 3> DisplayTransform::apply(std::array<float, 3> linear, const DisplaySettings& settings,
                                             Encoding enc) const {
  for (float v : linear)
    if (!std::isfinite(v)) {
      const float nan = std::numeric_limits<float>::quiet_NaN();
      return {nan, nan, nan};
    }
  const float scale = exposure_scale(settings.exposure);
  const auto offset = static_cast<float>(settings.offset);
  for (float& v : linear) v = expose(v, scale, offset);
  isolate_row(linear.data(), 1, settings.channel);
  if (enc == Encoding::SceneLinear && settings.false_colour) false_colour_row(linear.data(), 1);
  else if (enc == Encoding::SceneLinear) impl_->pipeline(settings).apply_row(linear.data(), 1);
  for (float& v : linear) v = clamp01(v);
  if (settings.gamma != 1.0) {
    const auto inverse = static_cast<float>(1.0 / settings.gamma);
    for (float& v : linear) v = std::pow(v, inverse);
  }
  return linear;
}

QImage DisplayTransform::render(const Image& image, int first_channel, int count, const Rect& rect,
                                const DisplaySettings& s, Encoding enc) const {
  if (rect.width < 0 || rect.height < 0 || !image.bounds().contains(rect))
    throw Error(ErrorKind::Usage, "display rect " + rect.to_string() + " is not inside the image (" +
                                      std::to_string(image.width()) + "x" + std::to_string(image.height()) + ")");
  if (first_channel < 0 || count < 1 || first_channel + count > image.channels())
    throw Error(ErrorKind::Usage, "display channels [" + std::to_string(first_channel) + ", " +
                                      std::to_string(first_channel + count) + ") are not within the image's " +
                                      std::to_string(image.channels()) + " channels");
  if (rect.empty()) return {};
  if (!(s.gamma > 0) || !std::isfinite(s.gamma))
    throw Error(ErrorKind::Usage, "display gamma " + std::to_string(s.gamma) + ": expected a positive number");
  if (rect.width > std::numeric_limits<int>::max() || rect.height > std::numeric_limits<int>::max())
    throw Error(ErrorKind::Usage, "display rect " + rect.to_string() + " is too large for a QImage");

  // Resolve (and build) the pipeline before the parallel loop, so errors come from this thread.
  const Pipeline pipeline = enc == Encoding::SceneLinear ? impl_->pipeline(s) : Pipeline{};
  QImage out(static_cast<int>(rect.width), static_cast<int>(rect.height), QImage::Format_RGB32);
  if (out.isNull())
    throw Error(ErrorKind::Usage, "display rect " + rect.to_string() + ": cannot allocate the 8-bit image");

  // bits() once here: the non-const scanLine() may detach, which is not safe from several threads.
  uchar* const bits = out.bits();
  const auto bytes_per_line = static_cast<int64_t>(out.bytesPerLine());
  const float scale = exposure_scale(s.exposure);
  const auto offset = static_cast<float>(s.offset);
  const int channels = image.channels();
  const int64_t width = rect.width;

  tbb::parallel_for(tbb::blocked_range<int64_t>(0, rect.height), [&](const tbb::blocked_range<int64_t>& rows) {
    std::vector<float> rgb(static_cast<size_t>(width) * 3);
    std::vector<uint8_t> codes(static_cast<size_t>(width) * 3);
    std::vector<uint8_t> bad(static_cast<size_t>(width));
    for (int64_t y = rows.begin(); y < rows.end(); ++y) {
      const float* src = image.row(rect.y + y).data() + rect.x * channels + first_channel;
      switch (std::min(count, 3)) {
        case 1: expose_row<1>(src, channels, width, scale, offset, rgb.data(), bad.data()); break;
        case 2: expose_row<2>(src, channels, width, scale, offset, rgb.data(), bad.data()); break;
        default: expose_row<3>(src, channels, width, scale, offset, rgb.data(), bad.data()); break;
      }
      isolate_row(rgb.data(), width, s.channel);
      if (enc == Encoding::SceneLinear && s.false_colour) false_colour_row(rgb.data(), width);
      else if (enc == Encoding::SceneLinear) pipeline.apply_row(rgb.data(), width);
      if (s.clipping) clip_row(rgb.data(), width, bad.data());
      if (s.gamma != 1.0) {
        const auto inverse = static_cast<float>(1.0 / s.gamma);
        for (float& v : rgb) v = std::pow(clamp01(v), inverse);
      }
      // Quantise the flat row (vectorised), then pack.
      for (size_t i = 0; i < codes.size(); ++i) codes[i] = to_code(rgb[i]);
      auto* line = reinterpret_cast<uint32_t*>(bits + y * bytes_per_line);
      for (int64_t x = 0; x < width; ++x) {
        const uint8_t* c = codes.data() + x * 3;
        const uint32_t packed = 0xff000000u | (uint32_t{c[0]} << 16) | (uint32_t{c[1]} << 8) | uint32_t{c[2]};
        const uint8_t flag = bad[static_cast<size_t>(x)];
        line[x] = flag == kBad ? kMagenta : flag == kHigh ? kClipHigh : flag == kLow ? kClipLow : packed;
      }
    }
  });
  return out;
}

}  // namespace residue::ui
