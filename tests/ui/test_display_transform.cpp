// ui/display_transform: the shipped OCIO config's views against the formulas in core/metrics/tonemap.h,
// render() against apply(), non-finite pixels, errors, and the $OCIO fallback chain.
#include <QElapsedTimer>
#include <QTemporaryDir>
#include <QtTest>

#include <array>
#include <cmath>
#include <ctime>
#include <fstream>
#include <future>
#include <random>
#include <string>
#include <vector>

#include "core/image/colormap.h"
#include "core/metrics/tonemap.h"
#include "core/util/error.h"
#include "core/util/resources.h"
#include "ui/display_transform.h"

using residue::Image;
using residue::Rect;
using residue::ui::DisplaySettings;
using residue::ui::DisplayTransform;
using residue::ui::Encoding;

namespace {

// OCIO vs the formulas (measured ~1e-5 for Standard, ~2e-7 for Filmic). Tighter than 1/1000: moving Hable's
// white point from 11.2 to 11.0 changes the curve by only 1.8e-3, and that must fail.
constexpr float kTolerance = 1e-4f;

std::filesystem::path shipped_config() {
  const auto p = residue::find_resource("ocio/config.ocio");
  return p ? *p : std::filesystem::path{};
}

// n values log-spaced over [lo, hi].
std::vector<float> log_spaced(double lo, double hi, int n) {
  std::vector<float> v;
  for (int i = 0; i < n; ++i) v.push_back(static_cast<float>(lo * std::pow(hi / lo, i / double(n - 1))));
  return v;
}

int code(float v) { return static_cast<int>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f)); }

// Runs `f`, expecting residue::Error of `kind` whose message contains `needle`.
template <typename F>
bool throws_error(F&& f, residue::ErrorKind kind, const std::string& needle, std::string* message = nullptr) {
  try {
    f();
  } catch (const residue::Error& e) {
    if (message) *message = e.what();
    return e.kind() == kind && std::string(e.what()).find(needle) != std::string::npos;
  }
  return false;
}

// A 7x5, 4-channel image spanning negatives, darks and HDR, with a NaN (2,1).R, an Inf (5,3).B, and an Inf
// in channel 3 only at (1,1).
Image test_image() {
  Image img(7, 5, 4);
  for (int64_t y = 0; y < 5; ++y)
    for (int64_t x = 0; x < 7; ++x)
      for (int c = 0; c < 4; ++c)
        img.at(x, y, c) = static_cast<float>(0.002 * std::pow(2.3, double(x + 2 * y + c)) - (x == 0 ? 0.01 : 0.0));
  img.at(2, 1, 0) = std::numeric_limits<float>::quiet_NaN();
  img.at(5, 3, 2) = std::numeric_limits<float>::infinity();
  img.at(1, 1, 3) = -std::numeric_limits<float>::infinity();
  return img;
}

}  // namespace

class TestDisplayTransform : public QObject {
  Q_OBJECT

 private:
  std::shared_ptr<const DisplayTransform> shipped_;

  // Every pixel of `out` (rendered from `rect` of `img`) equals apply() quantised, within one code value;
  // non-finite inputs are magenta.
  void check_render(const DisplayTransform& t, const Image& img, int first, int count, const Rect& rect,
                    const DisplaySettings& s, Encoding enc) {
    const QImage out = t.render(img, first, count, rect, s, enc);
    QCOMPARE(out.format(), QImage::Format_RGB32);
    QCOMPARE(out.width(), int(rect.width));
    QCOMPARE(out.height(), int(rect.height));
    for (int y = 0; y < out.height(); ++y)
      for (int x = 0; x < out.width(); ++x) {
        std::array<float, 3> in{};
        for (int c = 0; c < 3; ++c) in[c] = img.at(rect.x + x, rect.y + y, first + (count == 1 ? 0 : c));
        if (count == 2) in[2] = 0.0f;
        const QRgb px = out.pixel(x, y);
        const auto want = t.apply(in, s, enc);
        const QString where = QString("pixel (%1,%2), channels %3+%4").arg(x).arg(y).arg(first).arg(count);
        if (std::isnan(want[0])) {
          QVERIFY2(px == qRgb(255, 0, 255), qPrintable(where + " should be magenta"));
          continue;
        }
        QVERIFY2(std::abs(qRed(px) - code(want[0])) <= 1, qPrintable(where + " R"));
        QVERIFY2(std::abs(qGreen(px) - code(want[1])) <= 1, qPrintable(where + " G"));
        QVERIFY2(std::abs(qBlue(px) - code(want[2])) <= 1, qPrintable(where + " B"));
        if (count == 1) QVERIFY2(qRed(px) == qGreen(px) && qGreen(px) == qBlue(px), qPrintable(where + " grey"));
      }
  }

 private slots:
  void initTestCase() {
    qunsetenv("OCIO");
    QVERIFY2(!shipped_config().empty(), "resources/ocio/config.ocio not found by find_resource");
    shipped_ = DisplayTransform::load(shipped_config());
    QVERIFY(shipped_->uses_ocio());
  }

  void shippedConfigListsDisplaysAndViews() {
    QCOMPARE(shipped_->displays(), std::vector<std::string>{"sRGB"});
    QCOMPARE(shipped_->views("sRGB"), (std::vector<std::string>{"Filmic (Hable)", "Standard", "Raw"}));
    QCOMPARE(shipped_->default_display(), std::string("sRGB"));
    QCOMPARE(shipped_->default_view("sRGB"), std::string("Filmic (Hable)"));
    QVERIFY(shipped_->views("No such display").empty());
    QCOMPARE(shipped_->source(), shipped_config().string());
  }

  void standardIsSrgbOetf() {
    const auto values = log_spaced(1e-4, 10.0, 200);
    int checked = 0;
    float worst = 0.0f;
    for (const double exposure : {0.0, 1.0, -2.5})
      for (const double offset : {0.0, 0.01, -0.002}) {
        const DisplaySettings s{exposure, offset, "sRGB", "Standard"};
        for (const float v : values) {
          const std::array<float, 3> in{v, 0.5f * v, 3.0f * v};
          const auto out = shipped_->apply(in, s, Encoding::SceneLinear);
          for (int c = 0; c < 3; ++c) {
            const float lin = static_cast<float>(in[c] * std::exp2(exposure) + offset);
            const float want = residue::srgb_oetf(std::clamp(lin, 0.0f, 1.0f));
            worst = std::max(worst, std::abs(out[c] - want));
            if (std::abs(out[c] - want) > kTolerance)
              QFAIL(qPrintable(QString("Standard(%1, exposure %2, offset %3) = %4, srgb_oetf gives %5")
                                   .arg(double(in[c])).arg(exposure).arg(offset).arg(double(out[c])).arg(double(want))));
            ++checked;
          }
        }
      }
    QCOMPARE(checked, 200 * 3 * 9);
    qDebug("Standard through OCIO: largest difference from srgb_oetf %.2e", double(worst));
    // Values above 1 clip under Standard (OCIO's fast pow gives 1 - ~1e-5 at exactly 1).
    const auto clipped = shipped_->apply({4.0f, 1.0f, 0.0f}, {0, 0, "sRGB", "Standard"}, Encoding::SceneLinear);
    QCOMPARE(clipped[0], 1.0f);
    QVERIFY(std::abs(clipped[1] - 1.0f) < 1e-4f);
    QCOMPARE(clipped[2], 0.0f);
  }

  void filmicIsTheMetricsTonemap() {
    const auto values = log_spaced(1e-4, 100.0, 200);
    float worst = 0.0f;
    for (const char* view : {"Filmic (Hable)", ""}) {  // "" = the default view, which must be Filmic
      const DisplaySettings s{0.0, 0.0, "", view};
      for (const float v : values) {
        const auto out = shipped_->apply({v, 0.25f * v, 4.0f * v}, s, Encoding::SceneLinear);
        const std::array<float, 3> want{residue::tonemap_filmic_srgb(v), residue::tonemap_filmic_srgb(0.25f * v),
                                        residue::tonemap_filmic_srgb(4.0f * v)};
        for (int c = 0; c < 3; ++c) {
          worst = std::max(worst, std::abs(out[c] - want[c]));
          if (std::abs(out[c] - want[c]) > kTolerance)
            QFAIL(qPrintable(QString("Filmic(%1) = %2, tonemap_filmic_srgb gives %3")
                                 .arg(double(v)).arg(double(out[c])).arg(double(want[c]))));
        }
      }
    }
    qDebug("Filmic (Hable) through OCIO: largest difference from tonemap_filmic_srgb %.2e", double(worst));
    // Exposure applies before the curve; negatives and 0 give black.
    const auto exposed = shipped_->apply({0.3f, 0.0f, -2.0f}, {1.5, 0.0, "sRGB", "Filmic (Hable)"}, Encoding::SceneLinear);
    QVERIFY(std::abs(exposed[0] - residue::tonemap_filmic_srgb(0.3f * std::exp2(1.5f))) < kTolerance);
    QCOMPARE(exposed[1], 0.0f);
    QCOMPARE(exposed[2], 0.0f);
    // The views really differ: at 0.5, filmic is well below the plain OETF.
    const float standard = shipped_->apply({0.5f, 0.5f, 0.5f}, {0, 0, "sRGB", "Standard"}, Encoding::SceneLinear)[0];
    const float filmic = shipped_->apply({0.5f, 0.5f, 0.5f}, {0, 0, "sRGB", ""}, Encoding::SceneLinear)[0];
    QVERIFY(standard - filmic > 0.1f);
  }

  // Decision: Raw is exposure/offset then clamp to [0,1] (a display cannot show more), no transfer curve.
  void rawIsClampedIdentity() {
    const DisplaySettings s{0.0, 0.0, "sRGB", "Raw"};
    QCOMPARE(shipped_->apply({-0.5f, 0.25f, 0.7f}, s, Encoding::SceneLinear), (std::array<float, 3>{0.0f, 0.25f, 0.7f}));
    QCOMPARE(shipped_->apply({3.0f, 1.0f, 0.0f}, s, Encoding::SceneLinear), (std::array<float, 3>{1.0f, 1.0f, 0.0f}));
    const DisplaySettings up{1.0, 0.125, "sRGB", "Raw"};
    QCOMPARE(shipped_->apply({0.25f, 0.0f, 0.3f}, up, Encoding::SceneLinear), (std::array<float, 3>{0.625f, 0.125f, 0.725f}));
  }

  void dataIsClampOnly() {
    // Whatever view is chosen, Data skips OCIO.
    for (const char* view : {"Filmic (Hable)", "Standard", "Raw"}) {
      const DisplaySettings s{-1.0, 0.1, "sRGB", view};
      const auto out = shipped_->apply({0.5f, 2.0f, -1.0f}, s, Encoding::Data);
      QCOMPARE(out, (std::array<float, 3>{0.35f, 1.0f, 0.0f}));
    }
  }

  void nonFiniteGivesNaN() {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    for (const Encoding enc : {Encoding::SceneLinear, Encoding::Data})
      for (const std::array<float, 3> in : {std::array<float, 3>{nan, 0.5f, 0.5f}, {0.5f, inf, 0.5f}, {0.5f, 0.5f, -inf}}) {
        const auto out = shipped_->apply(in, {}, enc);
        QVERIFY(std::isnan(out[0]) && std::isnan(out[1]) && std::isnan(out[2]));
      }
    // Finite but huge stays a number even with exposure (saturates to white).
    const auto big = shipped_->apply({3e38f, 3e38f, 3e38f}, {8.0, 0.0, "", ""}, Encoding::SceneLinear);
    QCOMPARE(big, (std::array<float, 3>{1.0f, 1.0f, 1.0f}));
  }

  void unknownDisplayOrViewIsUsageError() {
    QVERIFY(throws_error([&] { shipped_->apply({0, 0, 0}, {0, 0, "sRGB", "ACES"}, Encoding::SceneLinear); },
                         residue::ErrorKind::Usage, "ACES"));
    QVERIFY(throws_error([&] { shipped_->apply({0, 0, 0}, {0, 0, "P3", ""}, Encoding::SceneLinear); },
                         residue::ErrorKind::Usage, "P3"));
  }

  void renderMatchesApply() {
    const Image img = test_image();
    for (const char* view : {"Filmic (Hable)", "Standard", "Raw"})
      for (const Rect& rect : {img.bounds(), Rect{1, 1, 5, 3}, Rect{6, 4, 1, 1}}) {
        const DisplaySettings s{0.7, 0.003, "sRGB", view};
        check_render(*shipped_, img, 0, 3, rect, s, Encoding::SceneLinear);
        check_render(*shipped_, img, 1, 3, rect, s, Encoding::SceneLinear);
        check_render(*shipped_, img, 3, 1, rect, s, Encoding::SceneLinear);
        check_render(*shipped_, img, 2, 2, rect, s, Encoding::SceneLinear);
        check_render(*shipped_, img, 0, 4, rect, s, Encoding::Data);
      }
  }

  // One channel alone is that channel as grey through the same view: the image with it in all three channels;
  // luminance is Rec. 709's Y (issue 53, item 16).
  void aChannelAloneIsItsGrey() {
    const Image img = test_image();
    for (const char* view : {"Filmic (Hable)", "Standard"}) {
      for (auto [channel, weights] : std::vector<std::pair<residue::ui::DisplayChannel, std::array<double, 3>>>{
               {residue::ui::DisplayChannel::R, {1, 0, 0}},
               {residue::ui::DisplayChannel::G, {0, 1, 0}},
               {residue::ui::DisplayChannel::B, {0, 0, 1}},
               {residue::ui::DisplayChannel::Luminance, {0.2126, 0.7152, 0.0722}}}) {
        Image grey(img.width(), img.height(), 3);
        for (int64_t y = 0; y < img.height(); ++y)
          for (int64_t x = 0; x < img.width(); ++x) {
            // Exposure first: it scales every channel alike, so the weights may come before it.
            const double v = weights[0] * img.at(x, y, 0) + weights[1] * img.at(x, y, 1) + weights[2] * img.at(x, y, 2);
            for (int c = 0; c < 3; ++c) grey.at(x, y, c) = static_cast<float>(v);
          }
        DisplaySettings alone{0.7, 0.0, "sRGB", view, channel};
        const DisplaySettings all{0.7, 0.0, "sRGB", view};
        const QImage a = shipped_->render(img, 0, 3, img.bounds(), alone, Encoding::SceneLinear);
        const QImage b = shipped_->render(grey, 0, 3, grey.bounds(), all, Encoding::SceneLinear);
        for (int y = 0; y < a.height(); ++y)
          for (int x = 0; x < a.width(); ++x) {
            const QRgb p = a.pixel(x, y), q = b.pixel(x, y);
            if (q == 0xffff00ffu) continue;  // a non-finite pixel of the grey image (a NaN spreads in the sum)
            QVERIFY2(std::abs(qRed(p) - qRed(q)) <= 1 && qRed(p) == qGreen(p) && qGreen(p) == qBlue(p),
                     qPrintable(QString("%1 at %2,%3: %4 vs %5").arg(residue::ui::to_string(channel)).arg(x).arg(y)
                                    .arg(qRed(p)).arg(qRed(q))));
          }
        QCOMPARE(residue::ui::display_channel_from_string(residue::ui::to_string(channel)), std::optional(channel));
      }
    }
    QVERIFY(!residue::ui::display_channel_from_string("alpha"));
  }

  // Gamma after the view: each display value v becomes v^(1/gamma), in render() as in apply(); a gamma that is no
  // positive number is refused (issue 53, item 17).
  void gammaComesAfterTheView() {
    const Image img = test_image();
    const DisplaySettings plain{0.7, 0.0, "sRGB", "Standard"};
    DisplaySettings g = plain;
    g.gamma = 2.2;
    const QImage a = shipped_->render(img, 0, 3, img.bounds(), plain, Encoding::SceneLinear);
    const QImage b = shipped_->render(img, 0, 3, img.bounds(), g, Encoding::SceneLinear);
    for (int y = 0; y < img.height(); ++y)
      for (int x = 0; x < img.width(); ++x) {
        if (a.pixel(x, y) == 0xffff00ffu) continue;  // not finite
        const auto v = shipped_->apply({img.at(x, y, 0), img.at(x, y, 1), img.at(x, y, 2)}, plain, Encoding::SceneLinear);
        const auto w = shipped_->apply({img.at(x, y, 0), img.at(x, y, 1), img.at(x, y, 2)}, g, Encoding::SceneLinear);
        QVERIFY(std::abs(w[0] - std::pow(v[0], 1.0f / 2.2f)) < 1e-6f);
        QVERIFY2(std::abs(qRed(b.pixel(x, y)) - code(w[0])) <= 1, qPrintable(QString("%1,%2").arg(x).arg(y)));
      }
    g.gamma = 0;
    QVERIFY(throws_error([&] { shipped_->render(img, 0, 3, img.bounds(), g, Encoding::SceneLinear); },
                         residue::ErrorKind::Usage, "gamma"));
  }

  // The clipping warning: where the view reaches white in a channel, red; where all channels are black, blue;
  // elsewhere the image; a non-finite pixel stays magenta.
  void clippingWarningsMarkWhatTheViewClips() {
    Image img(4, 1, 3);
    const float values[4][3] = {{100.0f, 0.1f, 0.1f}, {0.0f, 0.0f, 0.0f}, {0.2f, 0.3f, 0.4f}, {NAN, 0.2f, 0.2f}};
    for (int x = 0; x < 4; ++x)
      for (int c = 0; c < 3; ++c) img.at(x, 0, c) = values[x][c];
    DisplaySettings s{0.0, 0.0, "sRGB", "Standard"};
    s.clipping = true;
    const QImage out = shipped_->render(img, 0, 3, img.bounds(), s, Encoding::SceneLinear);
    QCOMPARE(out.pixel(0, 0), residue::ui::kClipHigh);
    QCOMPARE(out.pixel(1, 0), residue::ui::kClipLow);
    s.clipping = false;
    QCOMPARE(out.pixel(2, 0), shipped_->render(img, 0, 3, img.bounds(), s, Encoding::SceneLinear).pixel(2, 0));
    QCOMPARE(out.pixel(3, 0), 0xffff00ffu);
  }

  // False colour: luminance in stops about mid grey through turbo, in place of the view; mid grey is turbo's middle,
  // +-6.5 stops its ends (and beyond them clamped); exposure counts.
  void falseColourIsStopsAboutMidGrey() {
    Image img(4, 1, 3);
    const float ys[4] = {0.18f, 0.18f * std::exp2(6.5f), 0.18f * std::exp2(-8.0f), 0.09f};
    for (int x = 0; x < 4; ++x)
      for (int c = 0; c < 3; ++c) img.at(x, 0, c) = ys[x];
    DisplaySettings s{0.0, 0.0, "sRGB", "Standard"};
    s.false_colour = true;
    const QImage out = shipped_->render(img, 0, 3, img.bounds(), s, Encoding::SceneLinear);
    const auto turbo = [](double t) {
      const auto c = residue::colormap_lookup(residue::Colormap::Turbo, t);
      return qRgb(c[0], c[1], c[2]);
    };
    QCOMPARE(out.pixel(0, 0), turbo(0.5));
    QCOMPARE(out.pixel(1, 0), turbo(1.0));
    QCOMPARE(out.pixel(2, 0), turbo(0.0));
    QCOMPARE(out.pixel(3, 0), turbo((6.5 - 1.0) / 13.0));  // a stop under mid grey
    s.exposure = 1.0;  // ... which one stop of exposure brings to mid grey
    QCOMPARE(shipped_->render(img, 0, 3, img.bounds(), s, Encoding::SceneLinear).pixel(3, 0), turbo(0.5));
  }

  void renderFlagsNonFiniteAndDrawsGrey() {
    const Image img = test_image();
    const DisplaySettings s;
    const QImage rgb = shipped_->render(img, 0, 3, img.bounds(), s, Encoding::SceneLinear);
    QCOMPARE(rgb.pixel(2, 1), qRgb(255, 0, 255));  // NaN in R
    QCOMPARE(rgb.pixel(5, 3), qRgb(255, 0, 255));  // Inf in B
    QVERIFY(rgb.pixel(1, 1) != qRgb(255, 0, 255));  // the Inf is in channel 3, not shown
    const QImage grey = shipped_->render(img, 3, 1, img.bounds(), s, Encoding::SceneLinear);
    QCOMPARE(grey.pixel(1, 1), qRgb(255, 0, 255));
    const QRgb g = grey.pixel(4, 2);
    const int want = code(residue::tonemap_filmic_srgb(img.at(4, 2, 3)));
    QVERIFY(std::abs(qRed(g) - want) <= 1);
    QVERIFY(qRed(g) == qGreen(g) && qGreen(g) == qBlue(g));
    // A sub-rect reads the right pixels: (2,1) of the image is (1,0) of rect (1,1,...).
    const QImage sub = shipped_->render(img, 0, 3, Rect{1, 1, 5, 3}, s, Encoding::SceneLinear);
    QCOMPARE(sub.pixel(1, 0), qRgb(255, 0, 255));
    QCOMPARE(sub.pixel(0, 0), rgb.pixel(1, 1));
    QCOMPARE(sub.pixel(4, 2), rgb.pixel(5, 3));
    QVERIFY(shipped_->render(img, 0, 3, Rect{3, 3, 0, 0}, s, Encoding::SceneLinear).isNull());
  }

  void renderRejectsBadArguments() {
    const Image img = test_image();
    const DisplaySettings s;
    const auto usage = residue::ErrorKind::Usage;
    QVERIFY(throws_error([&] { shipped_->render(img, 0, 3, Rect{0, 0, 8, 5}, s, Encoding::SceneLinear); }, usage, "0,0,8,5"));
    QVERIFY(throws_error([&] { shipped_->render(img, 0, 3, Rect{-1, 0, 2, 2}, s, Encoding::SceneLinear); }, usage, "-1,0,2,2"));
    QVERIFY(throws_error([&] { shipped_->render(img, 2, 3, img.bounds(), s, Encoding::SceneLinear); }, usage, "channels"));
    QVERIFY(throws_error([&] { shipped_->render(img, -1, 1, img.bounds(), s, Encoding::SceneLinear); }, usage, "channels"));
    QVERIFY(throws_error([&] { shipped_->render(img, 0, 0, img.bounds(), s, Encoding::SceneLinear); }, usage, "channels"));
  }

  // Several threads rendering through fresh (unbuilt) views at once give the single-threaded pictures.
  void renderIsThreadSafe() {
    const auto t = DisplayTransform::load(shipped_config());
    Image img(64, 48, 3);
    std::mt19937 rng(7);
    std::exponential_distribution<float> dist(0.5f);
    for (size_t i = 0; i < img.size(); ++i) img.data()[i] = dist(rng);
    const std::vector<std::string> views{"Filmic (Hable)", "Standard", "Raw", "Standard", "Filmic (Hable)", "Raw"};
    std::vector<std::future<QImage>> jobs;
    for (const auto& v : views)
      jobs.push_back(std::async(std::launch::async, [&, v] {
        return t->render(img, 0, 3, img.bounds(), {0.5, 0.0, "sRGB", v}, Encoding::SceneLinear);
      }));
    for (size_t i = 0; i < views.size(); ++i)
      QCOMPARE(jobs[i].get(), shipped_->render(img, 0, 3, img.bounds(), {0.5, 0.0, "sRGB", views[i]}, Encoding::SceneLinear));
  }

  void loadErrorsNameTheFile() {
    QTemporaryDir dir;
    QVERIFY(dir.isValid());
    const std::filesystem::path root = dir.path().toStdString();
    const auto input = residue::ErrorKind::Input;
    std::string message;
    QVERIFY(throws_error([&] { DisplayTransform::load(root / "missing.ocio"); }, input, "missing.ocio"));

    std::ofstream(root / "broken.ocio") << "ocio_profile_version: 2\nroles: [this is not\n";
    QVERIFY(throws_error([&] { DisplayTransform::load(root / "broken.ocio"); }, input, "broken.ocio", &message));
    qDebug("broken config: %s", message.c_str());

    // The shipped config without its LUT folder: the default (Filmic) view cannot be built, so load() fails.
    std::filesystem::copy_file(shipped_config(), root / "nolut.ocio");
    QVERIFY(throws_error([&] { DisplayTransform::load(root / "nolut.ocio"); }, input, "nolut.ocio", &message));
    QVERIFY2(message.find("hable_filmic_srgb.spi1d") != std::string::npos, message.c_str());
  }

  void loadDefaultFallsBack() {
    qputenv("OCIO", "/nonexistent/studio.ocio");
    auto t = DisplayTransform::load_default();
    QCOMPARE(t->source(), shipped_config().string());
    QVERIFY2(t->note().find("/nonexistent/studio.ocio") != std::string::npos, t->note().c_str());
    QVERIFY2(t->note().find("shipped fallback") != std::string::npos, t->note().c_str());

    qunsetenv("OCIO");
    t = DisplayTransform::load_default();
    QCOMPARE(t->source(), shipped_config().string());
    QVERIFY(t->uses_ocio());

    // A valid $OCIO is used as is (a copy of the shipped config with its LUTs in another folder).
    QTemporaryDir dir;
    const std::filesystem::path root = dir.path().toStdString();
    std::filesystem::copy(shipped_config().parent_path(), root, std::filesystem::copy_options::recursive);
    qputenv("OCIO", QByteArray::fromStdString((root / "config.ocio").string()));
    t = DisplayTransform::load_default();
    qunsetenv("OCIO");
    QCOMPARE(t->source(), (root / "config.ocio").string());
    QVERIFY2(t->note().find("$OCIO") != std::string::npos, t->note().c_str());
  }

  void builtinMatchesTheFormulas() {
    const auto t = DisplayTransform::builtin("test");
    QVERIFY(!t->uses_ocio());
    QCOMPARE(t->source(), std::string("built-in sRGB (no OCIO config)"));
    QCOMPARE(t->note(), std::string("test"));
    QCOMPARE(t->views(t->default_display()), shipped_->views(shipped_->default_display()));
    QCOMPARE(t->default_view("sRGB"), std::string("Filmic (Hable)"));
    for (const float v : log_spaced(1e-4, 100.0, 50)) {
      QCOMPARE(t->apply({v, v, v}, {}, Encoding::SceneLinear)[0], residue::tonemap_filmic_srgb(v));
      QCOMPARE(t->apply({v, v, v}, {0, 0, "sRGB", "Standard"}, Encoding::SceneLinear)[1], residue::srgb_oetf(v));
      QCOMPARE(t->apply({v, v, v}, {0, 0, "sRGB", "Raw"}, Encoding::SceneLinear)[2], std::min(v, 1.0f));
    }
    check_render(*t, test_image(), 0, 3, Rect{0, 0, 7, 5}, {0.3, 0.0, "", ""}, Encoding::SceneLinear);
  }

  // Not a limit: prints the time of a 4096x4096 Filmic render (set RESIDUE_DISPLAY_BENCH=1 to run it).
  void timingFilmic4k() {
    if (qEnvironmentVariableIsEmpty("RESIDUE_DISPLAY_BENCH")) QSKIP("set RESIDUE_DISPLAY_BENCH=1 to time a 4K render");
    Image img(4096, 4096, 3);
    std::mt19937 rng(1);
    std::exponential_distribution<float> dist(1.0f);
    for (size_t i = 0; i < img.size(); ++i) img.data()[i] = dist(rng);
    const DisplaySettings s{0.5, 0.0, "sRGB", "Filmic (Hable)"};
    shipped_->render(img, 0, 3, Rect{0, 0, 16, 16}, s, Encoding::SceneLinear);  // builds the processor
    // Wall time, and CPU time of all threads (std::clock), which says more on a busy machine.
    const auto timed = [&](const char* name, const DisplaySettings& settings, Encoding enc) {
      QElapsedTimer timer;
      timer.start();
      const std::clock_t cpu = std::clock();
      const QImage out = shipped_->render(img, 0, 3, img.bounds(), settings, enc);
      const double cpu_ms = 1000.0 * double(std::clock() - cpu) / CLOCKS_PER_SEC;
      qDebug("render 4096x4096 RGB, %s: %lld ms wall, %.0f ms CPU", name, static_cast<long long>(timer.elapsed()),
             cpu_ms);
      QCOMPARE(out.width(), 4096);
    };
    for (int run = 0; run < 3; ++run) timed("Filmic (Hable)", s, Encoding::SceneLinear);
    // For comparison: Standard, and the loop without OCIO (Raw is a no-op processor, skipped; Data skips OCIO).
    timed("Standard", {0.5, 0.0, "sRGB", "Standard"}, Encoding::SceneLinear);
    timed("Raw", {0.5, 0.0, "sRGB", "Raw"}, Encoding::SceneLinear);
    timed("Data", {0.5, 0.0, "", ""}, Encoding::Data);
  }
};

QTEST_MAIN(TestDisplayTransform)
#include "test_display_transform.moc"
