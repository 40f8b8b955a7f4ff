// What the viewer suites share: opening the bundled example in a window, waiting until nothing runs, reading an
// EXR back with OpenImageIO (independent of core/io), comparing images.
#pragma once

#include <QSignalSpy>
#include <QString>
#include <QtTest>
#include <OpenImageIO/imageio.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>

#include "core/aov/aov_loader.h"
#include "ui/denoise_controller.h"
#include "ui/denoise_panel.h"
#include "ui/main_window.h"

namespace residue::ui::viewer_test {

inline const std::filesystem::path kExample = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";

// Waits until `done` holds and nothing runs on a worker any more.
inline bool settle(MainWindow& w, const std::function<bool()>& done, int ms = 60000) {
  return QTest::qWaitFor([&] { return done() && !w.busy(); }, ms);
}

// Holds the next run of `controller` at its first tile until release(): start the run, wait until reached(),
// cancel it (or look at it), release(). The run then goes on from a known point, so a test never races the
// worker. Its state is shared with the worker's copy of the gate, which may outlive this object.
class HeldAtFirstTile {
 public:
  explicit HeldAtFirstTile(DenoiseController* controller) : controller_(controller) {
    controller->setTileGate([state = state_] {
      std::unique_lock lock(state->mutex);
      if (state->reached) return;
      state->reached = true;
      state->changed.notify_all();
      state->changed.wait(lock, [&] { return state->released; });
    });
  }
  ~HeldAtFirstTile() {
    release();
    controller_->setTileGate({});
  }
  bool reached(std::chrono::seconds timeout = std::chrono::seconds(60)) {
    std::unique_lock lock(state_->mutex);
    return state_->changed.wait_for(lock, timeout, [&] { return state_->reached; });
  }
  void release() {
    {
      std::lock_guard lock(state_->mutex);
      state_->released = true;
    }
    state_->changed.notify_all();
  }

 private:
  struct State {
    std::mutex mutex;
    std::condition_variable changed;
    bool reached = false, released = false;
  };
  DenoiseController* controller_;
  std::shared_ptr<State> state_ = std::make_shared<State>();
};

// Runs `model` through the Denoise panel and waits until it has finished, successfully.
inline void runModel(MainWindow& w, const QString& model) {
  QVERIFY(w.denoisePanel()->selectModel(model));
  QSignalSpy finished(w.denoisePanel(), &DenoisePanel::finished);
  w.denoisePanel()->start();
  QVERIFY(settle(w, [&] { return finished.count() == 1; }));
  QVERIFY2(finished.at(0).at(0).toBool(), qPrintable(finished.at(0).at(1).toString()));
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
