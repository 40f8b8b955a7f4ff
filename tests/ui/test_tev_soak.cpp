// A soak of the viewer's tev server (issue 49): four clients stream images of random sizes and channel sets into
// one viewer, re-creating and closing them, with a cap on the streamed images' memory; the window shows the newest
// and is painted zoomed in to per-pixel values between steps. Nothing may crash, the images never hold more than
// the cap (a create beyond it is refused and that client reconnects), and at the end every image the viewer holds
// is exactly what its client last sent.
//
// RESIDUE_SOAK_IMAGES (default 40) images in all, RESIDUE_SOAK_MAX_EDGE (default 256) the largest edge,
// RESIDUE_SOAK_CAP_MIB (default 2) the cap; the recorded run (docs/RELIABILITY.md) is RESIDUE_SOAK_IMAGES=1000
// RESIDUE_SOAK_MAX_EDGE=2048 RESIDUE_SOAK_CAP_MIB=32.
#include <QTcpSocket>
#include <QtTest>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <random>

#include "support/tev_packet.h"
#include "ui/main_window.h"
#include "ui/tev_server.h"

using namespace residue;
using namespace residue::ui;
using residue::testing::TevPacket;

namespace {

int env_int(const char* name, int fallback) {
  const QByteArray v = qgetenv(name);
  return v.isEmpty() ? fallback : v.toInt();
}

// The process's peak resident memory (VmHWM), in MiB.
double peak_mib() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0;
}

struct Sent {
  int width = 0, height = 0;
  std::vector<std::string> channels;
  float base = 0;  // pixel value of channel c at (x, y): base + c + (y * width + x) * 1e-3
};

}  // namespace

class TevSoakTest : public QObject {
  Q_OBJECT
 private slots:
  void fourClientsStreamManyImages() {
    const int images = env_int("RESIDUE_SOAK_IMAGES", 40), max_edge = env_int("RESIDUE_SOAK_MAX_EDGE", 256);
    const size_t cap = static_cast<size_t>(env_int("RESIDUE_SOAK_CAP_MIB", 2)) << 20;
    MainWindow w;
    w.setInteractive(false);
    w.resize(1280, 720);
    w.show();
    QCOMPARE(w.listenForRenderers(0, cap), QString());
    std::vector<std::unique_ptr<QTcpSocket>> clients(4);
    const auto connect_client = [&](size_t k) {
      clients[k] = std::make_unique<QTcpSocket>();
      clients[k]->connectToHost(QHostAddress::LocalHost, w.tevServer()->port());
      QVERIFY(clients[k]->waitForConnected(5000));
    };
    for (size_t k = 0; k < clients.size(); ++k) connect_client(k);
    std::mt19937 rng(49);
    std::map<std::string, Sent> last;  // what each image's client last sent, for those the viewer accepted
    int refused = 0;
    static const std::vector<std::vector<std::string>> kLayouts = {
        {"R", "G", "B"}, {"R", "G", "B", "A"}, {"R", "G", "B", "albedo.R", "albedo.G", "albedo.B"}, {"Y"}};
    for (int i = 0; i < images; ++i) {
      const size_t k = rng() % clients.size();
      const std::string name = "client" + std::to_string(k) + "-" + std::to_string(rng() % 3);
      if (rng() % 10 == 0) {  // now and then a client closes an image
        const std::vector<uint8_t> close = TevPacket(2).str(name).done();
        QVERIFY(clients[k]->write(reinterpret_cast<const char*>(close.data()), static_cast<qint64>(close.size())) > 0);
        QVERIFY(QTest::qWaitFor([&] { return w.tevServer()->images().find(name) == nullptr; }, 10000));
        last.erase(name);
        continue;
      }
      // Sizes 1 .. max_edge: half of them spread over decades (many small), half uniform (many large).
      const auto edge = [&] {
        if (rng() % 2) return 1 + static_cast<int>(rng() % static_cast<unsigned>(max_edge));
        return std::max(1, static_cast<int>(std::exp(std::uniform_real_distribution<double>(0, std::log(max_edge))(rng))));
      };
      Sent s{edge(), edge(), kLayouts[rng() % kLayouts.size()], static_cast<float>(i)};
      TevPacket create(4);
      create.u8(1).str(name).i32(s.width).i32(s.height).i32(static_cast<int32_t>(s.channels.size()));
      for (const auto& c : s.channels) create.str(c);
      std::vector<std::vector<uint8_t>> packets = {create.done()};
      const int tile = 128;
      for (int ty = 0; ty < s.height; ty += tile)
        for (int tx = 0; tx < s.width; tx += tile) {
          const int tw = std::min(tile, s.width - tx), th = std::min(tile, s.height - ty);
          TevPacket update(5);
          update.u8(0).str(name).i32(static_cast<int32_t>(s.channels.size()));
          for (const auto& c : s.channels) update.str(c);
          update.i32(tx).i32(ty).i32(tw).i32(th);
          for (size_t c = 0; c < s.channels.size(); ++c)
            for (int y = ty; y < ty + th; ++y)
              for (int x = tx; x < tx + tw; ++x)
                update.f32(s.base + static_cast<float>(c) + static_cast<float>(y * s.width + x) * 1e-3f);
          packets.push_back(update.done());
        }
      QSignalSpy errors(w.tevServer(), &TevServer::protocolError);
      for (const auto& p : packets) {
        clients[k]->write(reinterpret_cast<const char*>(p.data()), static_cast<qint64>(p.size()));
        while (clients[k]->bytesToWrite() > 0 && clients[k]->state() == QAbstractSocket::ConnectedState)
          clients[k]->waitForBytesWritten(1000), QCoreApplication::processEvents();
      }
      const auto arrived = [&] {
        const ipc::LiveImage* live = w.tevServer()->images().find(name);
        return errors.count() > 0 || (live && live->pixels.width() == s.width && live->pixels.height() == s.height &&
                                      live->pixels.at(s.width - 1, s.height - 1, 0) ==
                                          s.base + static_cast<float>((s.height - 1) * s.width + s.width - 1) * 1e-3f);
      };
      QVERIFY2(QTest::qWaitFor(arrived, 30000), name.c_str());
      QVERIFY(w.tevServer()->images().bytes() <= cap);
      if (errors.count() > 0) {  // over the cap: refused, naming the image; the client reconnects
        QVERIFY2(errors.at(0).at(0).toString().contains(QString::fromStdString("'" + name + "'")),
                 qPrintable(errors.at(0).at(0).toString()));
        ++refused;
        last.erase(name);  // a refused re-create keeps the old image: it is checked as the server holds it
        connect_client(k);
      } else {
        last[name] = s;
      }
      if (i % 5 == 0) {  // paint as a screen would, zoomed in far enough for per-pixel values now and then
        if (i % 10 == 0) w.canvas()->setView(64.0, w.canvas()->center());
        w.grab();
      }
    }
    // Every image the viewer holds that a client last sent in full is exactly that.
    for (const auto& [name, s] : last) {
      const ipc::LiveImage* live = w.tevServer()->images().find(name);
      QVERIFY2(live, name.c_str());
      QCOMPARE(live->pixels.width(), s.width);
      for (int y = 0; y < s.height; y += std::max(1, s.height / 7))
        for (int x = 0; x < s.width; x += std::max(1, s.width / 7))
          for (size_t c = 0; c < s.channels.size(); ++c)
            QCOMPARE(live->pixels.at(x, y, static_cast<int>(c)),
                     s.base + static_cast<float>(c) + static_cast<float>(y * s.width + x) * 1e-3f);
    }
    QVERIFY(QTest::qWaitFor([&] { w.grab(); return !w.busy(); }, 60000));
    std::printf("[ measured ] %d images (edges 1..%d) from 4 clients: %d refused over the %zu MiB cap, %zu held at "
                "the end (%zu MiB), peak resident memory %.0f MiB\n",
                images, max_edge, refused, cap >> 20, w.tevServer()->images().size(),
                w.tevServer()->images().bytes() >> 20, peak_mib());
  }
};

QTEST_MAIN(TevSoakTest)
#include "test_tev_soak.moc"
