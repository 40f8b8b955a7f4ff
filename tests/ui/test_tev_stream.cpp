// The viewer as a tev server, driven headless: a client written here streams a render over tev's protocol in
// tiles, the way pbrt-v4 or tev's Python client does, and the viewer shows it (checked on the pixels it holds);
// clients sending malformed packets are disconnected while the viewer and the good client go on; a rewritten
// file is reloaded; --help needs no display.
#include <QProcess>
#include <QSignalSpy>
#include <QTemporaryDir>
#include <QDialog>
#include <QStatusBar>
#include <QTcpSocket>
#include <QTimer>
#include <QtTest>
#include <filesystem>

#include "support/tev_packet.h"
#include "ui/denoise_panel.h"
#include "ui/main_window.h"
#include "ui/session.h"
#include "ui/tev_server.h"

using namespace residue;
using namespace residue::ui;
using residue::testing::TevPacket;

namespace {

constexpr int kWidth = 12, kHeight = 10;
float value(int c, int x, int y, float frame) { return frame + 0.01f * static_cast<float>(c * 1000 + y * 100 + x); }

bool send(QTcpSocket& socket, const std::vector<uint8_t>& bytes) {
  const auto n = socket.write(reinterpret_cast<const char*>(bytes.data()), static_cast<qint64>(bytes.size()));
  socket.flush();
  return n == static_cast<qint64>(bytes.size());
}

// One progressive pass of the render: 5x4 tiles (the last ones overhang) of R,G,B and albedo, interleaved with
// a fourth, unused value per pixel (update v3: offsets 0..2, stride 4), as a renderer's framebuffer.
void streamPass(QTcpSocket& socket, float frame) {
  for (int ty = 0; ty < kHeight; ty += 4)
    for (int tx = 0; tx < kWidth; tx += 5) {
      const int w = 5, h = 4;
      TevPacket colour(6);
      colour.u8(0).str("pbrt live").i32(3).str("R").str("G").str("B").i32(tx).i32(ty).i32(w).i32(h);
      for (int64_t c = 0; c < 3; ++c) colour.i64(c);
      for (int c = 0; c < 3; ++c) colour.i64(4);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          for (int c = 0; c < 3; ++c) colour.f32(value(c, tx + x, ty + y, frame));
          colour.f32(1.0f);
        }
      QVERIFY(send(socket, colour.done()));
      TevPacket albedo(5);  // planar, v2
      albedo.u8(0).str("pbrt live").i32(3).str("albedo.R").str("albedo.G").str("albedo.B").i32(tx).i32(ty).i32(w).i32(h);
      for (int c = 0; c < 3; ++c)
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) albedo.f32(0.5f);
      QVERIFY(send(socket, albedo.done()));
    }
}

bool shows(MainWindow& w, float frame) {
  const auto stack = w.session()->stack();
  if (!stack || w.session()->liveName() != "pbrt live" || stack->width() != kWidth || !stack->albedo) return false;
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x)
      for (int c = 0; c < 3; ++c)
        if (stack->color.image.at(x, y, c) != value(c, x, y, frame) || stack->albedo->image.at(x, y, c) != 0.5f)
          return false;
  return true;
}

}  // namespace

class TevStreamTest : public QObject {
  Q_OBJECT
 private slots:
  void streamedRenderIsShownAndBadClientsAreDropped() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    QCOMPARE(w.listenForRenderers(0), QString());  // any free port
    const quint16 port = w.tevServer()->port();
    // small has no variant for colour and albedo alone (the default, multiscale, has one for colour alone).
    QVERIFY(w.denoisePanel()->selectModel("small"));

    QTcpSocket renderer;
    renderer.connectToHost(QHostAddress::LocalHost, port);
    QVERIFY(renderer.waitForConnected(5000));
    TevPacket create(4);
    create.u8(1).str("pbrt live").i32(kWidth).i32(kHeight).i32(6);
    for (const char* n : {"R", "G", "B", "albedo.R", "albedo.G", "albedo.B"}) create.str(n);
    QVERIFY(send(renderer, create.done()));
    streamPass(renderer, 1.0f);
    QVERIFY(QTest::qWaitFor([&] { return shows(w, 1.0f); }, 10000));
    QVERIFY(w.windowTitle().startsWith("pbrt live (live)"));
    // The stream has paused: the viewer denoises what it has (File > Denoise Streamed Images When They Pause).
    QVERIFY(QTest::qWaitFor([&] { return w.session()->denoised() != nullptr && !w.denoisePanel()->running(); },
                            30000));
    QCOMPARE(w.session()->denoised()->width(), kWidth);
    // Colour and albedo only: the selected family has no variant for that, so the cheapest that has one ran,
    // and the result says so.
    QVERIFY2(w.session()->denoisedDescription().contains("instead of small"), qPrintable(w.session()->denoisedDescription()));

    // Malformed clients: a length below a packet's, an unknown type, a huge declared length, a truncated update.
    QSignalSpy errors(w.tevServer(), &TevServer::protocolError);
    std::vector<std::vector<uint8_t>> bad = {
        {3, 0, 0, 0, 1},
        TevPacket(42).str("x").done(),
        {0xff, 0xff, 0xff, 0xff, 4},
        TevPacket(5).u8(0).str("pbrt live").i32(1).str("R").i32(0).i32(0).i32(1000).i32(1000).f32(1).done(),
        TevPacket(3).u8(0).str("never created").str("R").i32(0).i32(0).i32(1).i32(1).f32(1).done(),
    };
    for (const auto& bytes : bad) {
      QTcpSocket client;
      client.connectToHost(QHostAddress::LocalHost, port);
      QVERIFY(client.waitForConnected(5000));
      QVERIFY(send(client, bytes));
      QVERIFY2(QTest::qWaitFor([&] { return client.state() == QAbstractSocket::UnconnectedState; }, 5000),
               "the server should close a client that sends a malformed packet");
    }
    QCOMPARE(errors.count(), static_cast<int>(bad.size()));
    QVERIFY(errors.at(1).at(0).toString().contains("unknown type 42"));
    QVERIFY(errors.at(4).at(0).toString().contains("'never created', which was not created"));

    // The good client is still connected, and its next pass is shown.
    QCOMPARE(renderer.state(), QAbstractSocket::ConnectedState);
    streamPass(renderer, 2.0f);
    QVERIFY(QTest::qWaitFor([&] { return shows(w, 2.0f); }, 10000));

    // A second viewer finds the port taken and says so; the first goes on.
    MainWindow second;
    const QString error = second.listenForRenderers(port);
    QVERIFY2(error.contains(QString::number(port)) && error.contains("another Residue viewer"), qPrintable(error));
    QVERIFY(w.tevServer()->listening());
  }

  // A small test frame, fitted so far in that every pixel shows its values, then the real frame under another
  // name: the viewer goes on showing the new image (it once crashed drawing the old image's values at the new
  // size). Painted between every step, as a screen would be.
  void smallThenLargeImage() {
    MainWindow w;
    w.setInteractive(false);
    w.resize(1280, 720);
    w.show();
    QCOMPARE(w.listenForRenderers(0), QString());
    QTcpSocket renderer;
    renderer.connectToHost(QHostAddress::LocalHost, w.tevServer()->port());
    QVERIFY(renderer.waitForConnected(5000));
    const auto create_and_fill = [&](const std::string& name, int width, int height, int tile) {
      TevPacket create(4);
      create.u8(1).str(name).i32(width).i32(height).i32(3).str("R").str("G").str("B");
      QVERIFY(send(renderer, create.done()));
      for (int ty = 0; ty < height; ty += tile)
        for (int tx = 0; tx < width; tx += tile) {
          const int tw = std::min(tile, width - tx), th = std::min(tile, height - ty);
          TevPacket update(3);
          update.u8(0).str(name).str("R").i32(tx).i32(ty).i32(tw).i32(th);
          for (int i = 0; i < tw * th; ++i) update.f32(0.25f);
          QVERIFY(send(renderer, update.done()));
          w.grab();
        }
    };
    const auto shown = [&](const QString& name, int width) {
      w.grab();
      const auto stack = w.session()->stack();
      return stack && w.session()->liveName() == name && stack->width() == width && !w.busy() &&
             w.canvas()->panes().size() >= 1 && !w.canvas()->panes().front().display.isNull() &&
             w.canvas()->panes().front().display.width() == width;
    };
    create_and_fill("test frame", 4, 4, 4);
    QVERIFY(QTest::qWaitFor([&] { return shown("test frame", 4); }, 10000));
    QVERIFY2(w.canvas()->zoom() >= ImageCanvas::kValueTextZoom, qPrintable(QString::number(w.canvas()->zoom())));
    // The stream pauses: the viewer denoises the test frame, and its values are drawn in the denoised pane.
    QVERIFY(QTest::qWaitFor([&] { return w.session()->denoised() != nullptr && !w.denoisePanel()->running() && !w.busy(); },
                            30000));
    const int denoised_pane = w.paneIndex(Source::Denoised);
    QVERIFY(denoised_pane >= 0 && w.canvas()->panes()[static_cast<size_t>(denoised_pane)].values);
    w.grab();
    create_and_fill("beauty", 512, 512, 128);
    QVERIFY(QTest::qWaitFor([&] { return shown("beauty", 512); }, 20000));
    QVERIFY(w.canvas()->zoom() < ImageCanvas::kValueTextZoom);  // fitted to the new size
    QCOMPARE(w.session()->stack()->color.image.at(511, 511, 0), 0.25f);
  }

  // A stream never replaces the render shown unless it asks (grab_focus): an image created without it joins the
  // image list unshown and its updates stay there; one created with it is shown; "close image" closes its entry
  // (issue 53, item 6).
  void aStreamWithoutGrabFocusJoinsTheListUnshown() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    const std::filesystem::path example = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";
    w.openFiles({QString::fromStdString((example / "noisy.exr").string())});
    QVERIFY(QTest::qWaitFor([&] { return w.session()->hasStack() && !w.busy(); }, 30000));
    QCOMPARE(w.listenForRenderers(0), QString());
    QTcpSocket client;
    client.connectToHost(QHostAddress::LocalHost, w.tevServer()->port());
    QVERIFY(client.waitForConnected(5000));
    const auto create = [&](const std::string& name, bool focus) {
      TevPacket p(4);
      p.u8(focus ? 1 : 0).str(name).i32(2).i32(2).i32(3).str("R").str("G").str("B");
      QVERIFY(send(client, p.done()));
      TevPacket update(3);
      update.u8(0).str(name).str("R").i32(0).i32(0).i32(2).i32(2);
      for (int i = 0; i < 4; ++i) update.f32(0.5f);
      QVERIFY(send(client, update.done()));
    };
    QStringList shown;  // every render the canvas was given, by its stream name
    connect(w.session(), &Session::loaded, &w, [&] { shown << w.session()->liveName(); });
    create("background", false);
    QVERIFY(QTest::qWaitFor([&] { return w.session()->renderCount() == 2; }, 10000));
    QCOMPARE(w.session()->currentRender(), 0);
    QCOMPARE(w.session()->title(), QString("noisy.exr"));
    QCOMPARE(w.session()->renderTitle(1), QString("background (live)"));
    create("foreground", true);
    QVERIFY(QTest::qWaitFor([&] { return w.session()->liveName() == "foreground"; }, 10000));
    QCOMPARE(w.session()->renderCount(), 3);
    // The packets are handled in order: every update of "background" came before "foreground" was shown.
    QVERIFY2(!shown.contains("background"), qPrintable(shown.join(", ")));
    QVERIFY(send(client, TevPacket(2).str("background").done()));
    QVERIFY(QTest::qWaitFor([&] { return w.session()->renderCount() == 2; }, 10000));
    QCOMPARE(w.session()->liveName(), QString("foreground"));
  }

  // An "open image" packet naming a device (/dev/zero reads for ever) or a FIFO: refused at once, named, and the
  // viewer goes on taking packets (it used to freeze reading the device).
  void openImageOfADeviceIsRefused() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    QCOMPARE(w.listenForRenderers(0), QString());
    QTcpSocket client;
    client.connectToHost(QHostAddress::LocalHost, w.tevServer()->port());
    QVERIFY(client.waitForConnected(5000));
    QVERIFY(send(client, TevPacket(7).u8(1).str("/dev/zero").str("").done()));
    QVERIFY(QTest::qWaitFor([&] { return w.lastError().contains("'/dev/zero' is a device"); }, 10000));
    QVERIFY(!w.session()->hasStack());
    // Still serving: a created image arrives.
    TevPacket create(4);
    create.u8(1).str("after").i32(2).i32(2).i32(3).str("R").str("G").str("B");
    QVERIFY(send(client, create.done()));
    QVERIFY(QTest::qWaitFor([&] { return w.tevServer()->images().find("after") != nullptr; }, 10000));
  }

  // A client's failing "open image" requests (20 of them) never stack modal dialogs: each is said in the status
  // bar; a "create" beyond the streamed images' memory is refused naming the image, and the viewer goes on.
  void failingRequestsAreReportedNotStackedAsDialogs() {
    MainWindow w;
    w.setInteractive(true);  // as a user runs it: dialogs would open
    w.show();
    QCOMPARE(w.listenForRenderers(0, size_t{64} << 20), QString());
    int dialogs = 0;
    QTimer closer;
    connect(&closer, &QTimer::timeout, [&] {
      for (QWidget* top : QApplication::topLevelWidgets())
        if (auto* box = qobject_cast<QDialog*>(top); box && box->isVisible()) ++dialogs, box->reject();
    });
    closer.start(20);
    QTcpSocket client;
    client.connectToHost(QHostAddress::LocalHost, w.tevServer()->port());
    QVERIFY(client.waitForConnected(5000));
    for (int i = 0; i < 20; ++i)
      QVERIFY(send(client, TevPacket(7).u8(1).str("/no/such/render" + std::to_string(i) + ".exr").str("").done()));
    QVERIFY(QTest::qWaitFor([&] { return w.statusText().contains("render19.exr"); }, 10000));
    QSignalSpy errors(w.tevServer(), &TevServer::protocolError);
    TevPacket huge(4);
    huge.u8(1).str("huge").i32(16384).i32(16384).i32(4).str("R").str("G").str("B").str("A");
    QVERIFY(send(client, huge.done()));
    QVERIFY(QTest::qWaitFor([&] { return errors.count() == 1; }, 10000));
    QVERIFY2(errors.at(0).at(0).toString().contains("'huge'"), qPrintable(errors.at(0).at(0).toString()));
    QVERIFY(w.tevServer()->images().find("huge") == nullptr);
    QCOMPARE(dialogs, 0);
  }

  // `residue --help` on a machine without a display (no DISPLAY, no QT_QPA_PLATFORM) prints the options.
  void helpNeedsNoDisplay() {
    QProcess viewer;
    QProcessEnvironment env = QProcessEnvironment::systemEnvironment();
    for (const char* v : {"DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM"}) env.remove(v);
    viewer.setProcessEnvironment(env);
    viewer.start(RESIDUE_VIEWER_PATH, {"--help"});
    QVERIFY(viewer.waitForFinished(30000));
    QCOMPARE(viewer.exitCode(), 0);
    const QString out = QString::fromUtf8(viewer.readAllStandardOutput());
    QVERIFY2(out.contains("--no-ipc") && out.contains("--reference"), qPrintable(out));
  }

  // A renderer rewriting the open file, in place or by renaming a new one over it: the viewer reloads it.
  void rewrittenFileIsReloaded() {
    QTemporaryDir dir;
    const std::filesystem::path example = std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room";
    const std::filesystem::path render = std::filesystem::path(dir.path().toStdString()) / "render.exr";
    std::filesystem::copy_file(example / "noisy.exr", render);
    MainWindow w;
    w.setInteractive(false);
    w.openFiles({QString::fromStdString(render.string())});
    QVERIFY(QTest::qWaitFor([&] { return w.session()->hasStack() && !w.busy(); }, 30000));
    const float noisy = w.session()->stack()->color.image.at(10, 10, 0);
    const auto colour_is = [&](float v) {
      return w.session()->hasStack() && w.session()->stack()->color.image.at(10, 10, 0) == v && !w.busy();
    };
    // In place: the reference's bytes over the render (a different first pixel, no AOVs).
    std::filesystem::copy_file(example / "reference.exr", render, std::filesystem::copy_options::overwrite_existing);
    QVERIFY(QTest::qWaitFor([&] { return !colour_is(noisy) && w.session()->hasStack() && !w.session()->stack()->albedo; },
                            30000));
    const float reference = w.session()->stack()->color.image.at(10, 10, 0);
    QVERIFY(reference != noisy);
    // By a rename, as renderers that write atomically do (the watch follows the new file).
    const auto fresh = render.parent_path() / "render.tmp.exr";
    std::filesystem::copy_file(example / "noisy.exr", fresh);
    std::filesystem::rename(fresh, render);
    QVERIFY(QTest::qWaitFor([&] { return colour_is(noisy); }, 30000));
  }
};

QTEST_MAIN(TevStreamTest)
#include "test_tev_stream.moc"
