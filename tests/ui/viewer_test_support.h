// What the viewer suites share: opening the bundled example in a window, waiting until nothing runs, reading an
// EXR back with OpenImageIO (independent of core/io), comparing images.
#pragma once

#include <QString>
#include <QtTest>
#include <OpenImageIO/imageio.h>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>

#include "core/aov/aov_loader.h"
#include "ui/main_window.h"

namespace residue::ui::viewer_test {

inline const std::filesystem::path kExample = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";

// Waits until `done` holds and nothing runs on a worker any more.
inline bool settle(MainWindow& w, const std::function<bool()>& done, int ms = 60000) {
  return QTest::qWaitFor([&] { return done() && !w.busy(); }, ms);
}

// Opens the example render with its reference (a failure is the calling test's).
inline void openExample(MainWindow& w) {
  LoadOptions o;
  o.reference = kExample / "reference.exr";
  w.openFiles({QString::fromStdString((kExample / "noisy.exr").string())}, o);
  QVERIFY2(settle(w, [&] { return w.session()->hasStack(); }), qPrintable(w.lastError()));
}

inline Image readExr(const QString& path) {
  auto in = OIIO::ImageInput::open(path.toStdString());
  if (!in) return {};
  const auto& spec = in->spec();
  Image img(spec.width, spec.height, spec.nchannels);
  in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, img.data());
  return img;
}

inline double maxAbsDiff(const Image& a, const Image& b, int channels) {
  double m = 0;
  for (int64_t y = 0; y < a.height(); ++y)
    for (int64_t x = 0; x < a.width(); ++x)
      for (int c = 0; c < channels; ++c) m = std::max(m, std::abs(double(a.at(x, y, c)) - double(b.at(x, y, c))));
  return m;
}

}  // namespace residue::ui::viewer_test
