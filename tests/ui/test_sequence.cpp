// The viewer on a sequence (issue 51, item 7), driven headless on the committed Cycles shot (tests/data/shot: six
// 64x64 frames with motion vectors and a reference each): a frame opens as its sequence, each frame keeps its
// results, A follows the settings, the temporal column and map equal `residue-cli eval` on the same frames, the
// temporal model reads the frames beside and equals `residue-cli denoise --temporal`, play loops, every frame is
// denoised in turn, and numbered result files follow the frames. Every wait is on an event.
#include <QComboBox>
#include <QProcess>
#include <QSignalSpy>
#include <QSpinBox>
#include <QStandardPaths>
#include <QTableWidget>
#include <QTemporaryDir>
#include <QtTest>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/aov/aov_loader.h"
#include "core/io/metrics_report.h"
#include "ui/denoise_panel.h"
#include "ui/frame_bar.h"
#include "ui/heatmap_panel.h"
#include "ui/main_window.h"
#include "ui/metrics_panel.h"
#include "ui/session.h"
#include "viewer_test_support.h"

using namespace residue;
using namespace residue::ui;
using namespace residue::ui::viewer_test;
namespace fs = std::filesystem;

namespace {

const fs::path kShot = fs::path(RESIDUE_TEST_FIXTURES).parent_path() / "data/shot";

QString frameFile(int frame) { return QString::fromStdString((kShot / ("noisy.000" + std::to_string(frame) + ".exr")).string()); }

void openFrame(MainWindow& w, int frame) {
  w.openFiles({frameFile(frame)});
  QVERIFY2(settle(w, [&] { return w.session()->hasStack(); }), qPrintable(w.lastError()));
}

void go(MainWindow& w, int64_t frame) {
  QVERIFY(w.goToFrame(frame));
  QVERIFY(settle(w, [&] { return w.session()->frame() == frame && !w.session()->loading(); }));
}

// The Results table's temporal value of the row whose name starts with `name` (NaN when it shows none).
double temporalCell(MainWindow& w, const QString& name) {
  auto* table = w.metricsPanel()->findChild<QTableWidget*>("metricsTable");
  int column = -1, name_column = -1;
  for (int c = 0; c < table->columnCount(); ++c) {
    if (table->horizontalHeaderItem(c)->text() == "temporal") column = c;
    if (table->horizontalHeaderItem(c)->text() == "result") name_column = c;
  }
  if (column < 0 || name_column < 0 || table->isColumnHidden(column)) return std::nan("");
  for (int r = 0; r < table->rowCount(); ++r)
    if (table->item(r, name_column)->text().startsWith(name)) return table->item(r, column)->data(Qt::UserRole).toDouble();
  return std::nan("");
}

nlohmann::json cli(const QStringList& args) {
  QProcess p;
  p.start(RESIDUE_CLI_PATH, args);
  if (!p.waitForFinished(300000) || p.exitCode() != 0) {
    qWarning("%s", p.readAllStandardError().constData());
    return {};
  }
  const QByteArray out = p.readAllStandardOutput();
  return out.trimmed().startsWith('{') ? nlohmann::json::parse(out.toStdString()) : nlohmann::json::object();
}

}  // namespace

class TestSequence : public QObject {
  Q_OBJECT
 private slots:
  void initTestCase() {
    QStandardPaths::setTestModeEnabled(true);
    QSettings().clear();
  }

  void aFrameOpensAsItsSequenceWithEachFramesReference() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openFrame(w, 2);
    const auto& seq = w.session()->sequence();
    QVERIFY(seq.has_value());
    QCOMPARE(seq->frames, (std::vector<int64_t>{1, 2, 3, 4, 5, 6}));
    QCOMPARE(w.session()->frame(), int64_t{2});
    QVERIFY(w.frameBar()->isVisible());
    QCOMPARE(w.frameBar()->current(), int64_t{2});
    QVERIFY(w.session()->reference());
    QCOMPARE(QString::fromStdString(w.session()->stack()->reference->source.file).section('/', -1), QString("reference.0002.exr"));
    // Frames t-1 and t+1 are held beside it.
    QVERIFY(w.session()->frameStack(1) && w.session()->frameStack(3));
    QVERIFY(!w.session()->frameStack(4));
    go(w, 5);
    QCOMPARE(QString::fromStdString(w.session()->stack()->reference->source.file).section('/', -1), QString("reference.0005.exr"));
    QCOMPARE(w.frameBar()->current(), int64_t{5});
    // A file without a frame number is no sequence.
    w.openFiles({QString::fromStdString((kExample / "noisy.exr").string())});
    QVERIFY(settle(w, [&] { return !w.session()->sequence(); }));
    QVERIFY(!w.frameBar()->isVisible());
    QVERIFY(!w.goToFrame(2));
  }

  void eachFrameKeepsItsResultsAndAFollowsTheSettings() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openFrame(w, 2);
    runModel(w, "tiny");
    runModel(w, "small");
    const auto small2 = w.session()->result(w.session()->a())->image;
    w.session()->setA(w.session()->results().front().id);  // tiny as A, small as B
    w.session()->setB(w.session()->results().back().id);
    go(w, 3);
    QVERIFY(w.session()->results().empty());  // frame 3 has none yet
    runModel(w, "small");
    runModel(w, "tiny");
    go(w, 2);
    QCOMPARE(w.session()->results().size(), size_t(2));
    QCOMPARE(w.session()->result(w.session()->b())->image, small2);  // the same image, kept, not recomputed
    go(w, 3);
    // A was tiny on frame 2: tiny is A on frame 3 too, small is B.
    QCOMPARE(w.session()->result(w.session()->a())->name, QString("tiny fp32"));
    QCOMPARE(w.session()->result(w.session()->b())->name, QString("small fp32"));
    // Denoising again with kept settings shows the kept result: no new row.
    runModel(w, "small");
    QCOMPARE(w.session()->results().size(), size_t(2));
  }

  void theTemporalColumnAndMapEqualTheCli() {
    QTemporaryDir dir;
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openFrame(w, 2);
    runModel(w, "tiny");
    go(w, 3);
    runModel(w, "tiny");
    QVERIFY(settle(w, [&] { return !std::isnan(temporalCell(w, "tiny")) && !std::isnan(temporalCell(w, "noisy")); }));
    // The CLI on the same two frames: tiny's outputs written as float, then scored as a sequence.
    const QString out = dir.filePath("tiny.####.exr");
    QVERIFY(!cli({"denoise", QString::fromStdString((kShot / "noisy.####.exr").string()), "--frames", "2-3", "-m",
                  "tiny", "--float", "-o", out})
                 .is_null());
    const auto eval = cli({"eval", QString::fromStdString((kShot / "noisy.####.exr").string()), "-r",
                           QString::fromStdString((kShot / "reference.####.exr").string()), "--frames", "2-3",
                           "--denoised", out, "--json"});
    QVERIFY(eval.contains("temporal_relmse_compensated"));
    const double cli_noisy = eval["temporal_relmse_compensated"]["noisy"];
    const double cli_tiny = eval["temporal_relmse_compensated"]["denoised"];
    QVERIFY2(cli_noisy > 2 * cli_tiny, qPrintable(QString("%1 %2").arg(cli_noisy).arg(cli_tiny)));  // rows apart
    QVERIFY2(std::abs(temporalCell(w, "noisy") - cli_noisy) <= 1e-6 * cli_noisy,
             qPrintable(QString("%1 vs %2").arg(temporalCell(w, "noisy")).arg(cli_noisy)));
    QVERIFY2(std::abs(temporalCell(w, "tiny") - cli_tiny) <= 1e-4 * cli_tiny,
             qPrintable(QString("%1 vs %2").arg(temporalCell(w, "tiny")).arg(cli_tiny)));
    // What Export writes (the whole image's report, as JSON and CSV) carries the column's values.
    QVERIFY(settle(w, [&] { return w.metricsPanel()->wholeReport().rows.size() == 2; }));
    for (const io::MetricsRow& row : w.metricsPanel()->wholeReport().rows) {
      QVERIFY2(row.temporal_relmse_compensated.has_value(), row.name.c_str());
      QCOMPARE(*row.temporal_relmse_compensated, temporalCell(w, QString::fromStdString(row.name).section(' ', 0, 0)));
    }
    QVERIFY(QString::fromStdString(io::to_csv(w.metricsPanel()->wholeReport())).contains("temporal_relmse_compensated"));

    // The map: its mean over the pixels it scores is the column's value.
    QSignalSpy ready(w.heatmapPanel(), &HeatmapPanel::ready);
    auto* kind = w.heatmapPanel()->findChild<QComboBox*>("heatmapKind");
    kind->setCurrentIndex(kind->findText("temporal error (along the motion)"));
    QVERIFY(w.heatmapPanel()->temporal());
    QVERIFY(settle(w, [&] { return ready.count() > 0 && w.heatmapPanel()->map(); }));
    const Image& map = *w.heatmapPanel()->map();
    double sum = 0;
    int64_t n = 0, masked = 0;
    for (size_t i = 0; i < map.size(); ++i) {
      if (std::isfinite(map.data()[i])) sum += map.data()[i], ++n;
      else ++masked;
    }
    QVERIFY(masked > 0);  // the shot's truck uncovers the road: frame 2 does not show those pixels
    QVERIFY(std::abs(sum / double(n) - temporalCell(w, "tiny")) <= 1e-5 * temporalCell(w, "tiny"));
    QVERIFY(w.heatmapPanel()->title().startsWith("Temporal error along the motion of tiny fp32"));

    // Frame 1 has no frame before it: no temporal column, and the map says why.
    go(w, 1);
    QVERIFY(settle(w, [&] { return std::isnan(temporalCell(w, "noisy")); }));
    QVERIFY(!w.heatmapPanel()->map());
    for (const io::MetricsRow& row : w.metricsPanel()->wholeReport().rows)
      QVERIFY2(!row.temporal_relmse_compensated, row.name.c_str());
  }

  void theTemporalModelReadsTheFramesBesideAndEqualsTheCli() {
    QTemporaryDir dir;
    const QString out = dir.filePath("t.####.exr");
    QVERIFY(!cli({"denoise", QString::fromStdString((kShot / "noisy.####.exr").string()), "--frames", "1-2",
                  "--temporal", "--float", "-o", out})
                 .is_null());
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openFrame(w, 2);
    runModel(w, "multiscale-temporal");
    const Result* r2 = w.session()->result(w.session()->a());
    QVERIFY(!r2->description.contains("without"));
    const Image cli2 = readExr(dir.filePath("t.0002.exr"));
    QVERIFY(maxAbsDiff(*r2->image, cli2, 3) <= 1e-5);
    // On the first frame there is no t-1: the run says so and still equals the CLI's first frame.
    go(w, 1);
    runModel(w, "multiscale-temporal");
    const Result* r1 = w.session()->result(w.session()->a());
    QVERIFY2(r1->description.contains("without frame t-1"), qPrintable(r1->description));
    QVERIFY(maxAbsDiff(*r1->image, readExr(dir.filePath("t.0001.exr")), 3) <= 1e-5);
    // The neighbours count: frame 2 on its own (a copy without a frame number) denoises to another image.
    const QString single = dir.filePath("single.exr");
    QVERIFY(QFile::copy(frameFile(2), single));
    w.openFiles({single});
    QVERIFY(settle(w, [&] { return w.session()->hasStack() && !w.session()->sequence(); }));
    runModel(w, "multiscale-temporal");
    const Result* alone = w.session()->result(w.session()->a());
    QVERIFY2(alone->description.contains("no neighbouring frames"), qPrintable(alone->description));
    QVERIFY(maxAbsDiff(*alone->image, cli2, 3) > 1e-3);
  }

  void playLoopsThroughEveryFrame() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openFrame(w, 4);
    std::vector<int64_t> seen;
    connect(w.session(), &Session::frameChanged, &w, [&] { seen.push_back(w.session()->frame()); });
    w.frameBar()->findChild<QSpinBox*>("framesPerSecond")->setValue(60);
    w.setPlaying(true);
    QVERIFY2(QTest::qWaitFor([&] { return seen.size() >= 8; }, 60000), qPrintable(QString("%1 frames, playing %2").arg(seen.size()).arg(w.playing())));
    w.setPlaying(false);
    QCOMPARE(std::vector<int64_t>(seen.begin(), seen.begin() + 8), (std::vector<int64_t>{5, 6, 1, 2, 3, 4, 5, 6}));
    QVERIFY(settle(w, [&] { return true; }));
    const size_t stopped = seen.size();
    QVERIFY(!w.playing());
    w.stepFrame(+1);  // stepping at the end does not wrap when not playing
    QVERIFY(settle(w, [&] { return true; }));
    go(w, 6);
    w.stepFrame(+1);
    QVERIFY(settle(w, [&] { return true; }));
    QCOMPARE(w.session()->frame(), int64_t{6});
    QVERIFY(seen.size() <= stopped + 2);
  }

  void everyFrameIsDenoisedInTurn() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openFrame(w, 3);
    QVERIFY(w.denoisePanel()->selectModel("tiny"));
    w.denoiseEveryFrame();
    QVERIFY(w.denoisingEveryFrame());
    QVERIFY(settle(w, [&] { return !w.denoisingEveryFrame(); }, 120000));
    QCOMPARE(w.session()->frame(), int64_t{6});
    for (int64_t f = 1; f <= 6; ++f) {
      go(w, f);
      QCOMPARE(w.session()->results().size(), size_t(1));
      QVERIFY(w.session()->results().front().done() && w.session()->results().front().complete);
    }
    // With every frame's result, the temporal column has a value for it from frame 2 on.
    QVERIFY(settle(w, [&] { return !std::isnan(temporalCell(w, "tiny")); }));
  }

  void numberedResultFilesFollowTheFrames() {
    QTemporaryDir dir;
    const QString out = dir.filePath("nfor.####.exr");
    QVERIFY(!cli({"denoise", QString::fromStdString((kShot / "noisy.####.exr").string()), "--frames", "2-3", "-m",
                  "tiny", "--float", "-o", out})
                 .is_null());
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openFrame(w, 2);
    w.addResultFiles({dir.filePath("nfor.0002.exr")});
    QVERIFY(settle(w, [&] { return w.session()->results().size() == 1; }));
    go(w, 3);
    QVERIFY(settle(w, [&] { return w.session()->results().size() == 1 && w.session()->a() >= 0; }));
    QCOMPARE(w.session()->result(w.session()->a())->name, QString("nfor.0003.exr"));
    QVERIFY(maxAbsDiff(*w.session()->result(w.session()->a())->image, readExr(dir.filePath("nfor.0003.exr")), 3) == 0);
    QVERIFY(settle(w, [&] { return !std::isnan(temporalCell(w, "nfor")); }));
    // Frame 4 has no such file: nothing is added there.
    go(w, 4);
    QVERIFY(settle(w, [&] { return true; }));
    QVERIFY(w.session()->results().empty());
  }
};

QTEST_MAIN(TestSequence)
#include "test_sequence.moc"
