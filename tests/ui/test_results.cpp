// The viewer as a comparison workbench, driven headless: several results kept side by side (runs and files
// added), A and B, scores per result equal to core's, the heatmap of A against B and its shared range, the
// histogram, export-all read back, the run controller on its own, and a window that fits 1280x720.
#include <QAction>
#include <QDockWidget>
#include <QSignalSpy>
#include <QStandardPaths>
#include <QTabWidget>
#include <QTableWidget>
#include <QTemporaryDir>
#include <QtTest>
#include <OpenImageIO/imageio.h>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoiser.h"
#include "core/features/features.h"
#include "core/io/exr_writer.h"
#include "core/metrics/flip.h"
#include "core/metrics/metrics.h"
#include "core/nn/model_registry.h"
#include "ui/comparison_sheet.h"
#include "ui/denoise_controller.h"
#include "ui/denoise_panel.h"
#include "ui/export_all.h"
#include "ui/pixel_inspector.h"
#include "ui/heatmap_panel.h"
#include "ui/histogram.h"
#include "ui/help_overlay.h"
#include "ui/main_window.h"
#include "viewer_test_support.h"
#include "ui/metrics_panel.h"
#include "ui/pane_renderer.h"
#include "ui/session.h"

using namespace residue;
using namespace residue::ui;
using namespace residue::ui::viewer_test;

namespace {
void writeRgb(const QString& path, const Image& img) {
  io::ExrWriteOptions o;
  o.pixel_type = io::PixelType::Float;
  io::write_exr(path.toStdString(), img, o);
}

const io::MetricsRow* row(const io::MetricsReport& r, const std::string& name) {
  for (const auto& x : r.rows)
    if (x.name == name) return &x;
  return nullptr;
}
}  // namespace

class TestResults : public QObject {
  Q_OBJECT
 private slots:
  void initTestCase() {
    QStandardPaths::setTestModeEnabled(true);
    QSettings().clear();
  }

  void everyRunIsKeptWithItsOwnScores() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    runModel(w, "tiny");
    runModel(w, "small");
    const auto& results = w.session()->results();
    QCOMPARE(results.size(), size_t(2));
    QCOMPARE(results[0].name, QString("tiny fp32"));
    QCOMPARE(results[1].name, QString("small fp32"));
    QVERIFY(results[0].complete && results[1].complete);
    QVERIFY(results[0].seconds > 0);
    // The newest run is A; the other keeps its pixels.
    QCOMPARE(w.session()->a(), results[1].id);
    QVERIFY(maxAbsDiff(*results[0].image, *results[1].image, 3) > 1e-3);
    // One row per result (and the noisy input), each equal to core's scores of that image.
    const auto stack = w.session()->stack();
    QVERIFY(settle(w, [&] { return w.metricsPanel()->report().rows.size() == 3; }));
    const auto& report = w.metricsPanel()->report();
    for (const auto& r : results) {
      const auto* m = row(report, r.name.toStdString());
      QVERIFY2(m, qPrintable(r.name));
      const auto expected = metrics::compare(*r.image, stack->reference->image);
      QCOMPARE(m->scores.relmse, expected.relmse);
      QCOMPARE(m->scores.ssim, expected.ssim);
    }
    // The table shows them; sorting by relMSE puts the better one (small) first, the noisy input last.
    auto* table = w.metricsPanel()->findChild<QTableWidget*>("metricsTable");
    QVERIFY(table);
    QCOMPARE(table->rowCount(), 3);
    const auto column = [&](const QString& header) {
      for (int c = 0; c < table->columnCount(); ++c)
        if (table->horizontalHeaderItem(c)->text() == header) return c;
      return -1;
    };
    const int number = column("#"), name = column("result");
    table->sortByColumn(column("relMSE"), Qt::AscendingOrder);
    QVERIFY(table->item(0, name)->text().startsWith("small"));
    QVERIFY(table->item(2, name)->text().startsWith("noisy"));
    // Keys 1-9 follow the rows as shown, numbered in the # column (issue 53, item 9): 1 is now small.
    QCOMPARE(table->item(0, number)->text(), QString("1"));
    QCOMPARE(table->item(1, number)->text(), QString("2"));
    QCOMPARE(table->item(2, number)->text(), QString());  // the noisy input has no key
    QTest::keyClick(&w, Qt::Key_1);
    QCOMPARE(w.session()->a(), results[1].id);
    // Up/Down in the table move A with the highlight.
    table->setFocus();
    table->setCurrentCell(0, name);
    QTest::keyClick(table, Qt::Key_Down);
    QCOMPARE(w.session()->a(), results[0].id);
    table->sortByColumn(name, Qt::AscendingOrder);  // back to the order they came in, the noisy input first
    QCOMPARE(table->item(1, number)->text(), QString("1"));
    QVERIFY(table->item(1, name)->text().startsWith("tiny"));

    // Keys: 1 makes tiny A, Ctrl+2 small B; the B pane shows small's pixels.
    QTest::keyClick(&w, Qt::Key_1);
    QCOMPARE(w.session()->a(), results[0].id);
    QTest::keyClick(&w, Qt::Key_2, Qt::ControlModifier);
    QCOMPARE(w.session()->b(), results[1].id);
    QVERIFY(settle(w, [&] { return w.paneIndex(Source::Compare) >= 0; }));
    const auto& panes = w.canvas()->panes();
    QCOMPARE(panes[static_cast<size_t>(w.paneIndex(Source::Denoised))].label, QString("A: tiny fp32"));
    QCOMPARE(panes[static_cast<size_t>(w.paneIndex(Source::Compare))].label, QString("B: small fp32"));
    QCOMPARE(panes[static_cast<size_t>(w.paneIndex(Source::Compare))].values.get(), results[1].image.get());
    // Wipe, side by side and flip show A and B.
    QTest::keyClick(&w, Qt::Key_W);
    QCOMPARE(w.canvas()->wipeA(), w.paneIndex(Source::Denoised));
    QCOMPARE(w.canvas()->wipeB(), w.paneIndex(Source::Compare));
    QTest::keyClick(&w, Qt::Key_S);
    QCOMPARE(w.canvas()->layout(), ImageCanvas::Layout::Pair);
    QCOMPARE(w.canvas()->paneRects().size(), size_t(2));
    QTest::keyClick(&w, Qt::Key_Space);
    QCOMPARE(w.canvas()->layout(), ImageCanvas::Layout::Single);
    QCOMPARE(w.canvas()->current(), w.paneIndex(Source::Compare));
    QTest::keyClick(&w, Qt::Key_Space);
    QCOMPARE(w.canvas()->current(), w.paneIndex(Source::Denoised));

    // Asking for tiny again shows the kept result, without a run.
    QVERIFY(w.denoisePanel()->selectModel("tiny"));
    QSignalSpy again(w.denoisePanel(), &DenoisePanel::finished);
    w.denoisePanel()->start();
    QCOMPARE(again.count(), 1);
    QVERIFY(!w.denoisePanel()->running());
    QCOMPARE(w.session()->results().size(), size_t(2));

    // Difference (D): A - B, signed, in the diverging map on a range symmetric about 0 (issue 53, item 17).
    QTest::keyClick(&w, Qt::Key_D);
    QVERIFY(settle(w, [&] { return w.heatmapPanel()->map() && w.heatmapPanel()->title().contains("against"); }));
    QCOMPARE(w.heatmapPanel()->kind(), metrics::MapKind::SignedDifference);
    const Image diff = metrics::error_map(*results[0].image, *results[1].image, metrics::MapKind::SignedDifference);
    QCOMPARE(maxAbsDiff(*w.heatmapPanel()->map(), diff, 1), 0.0);
    QCOMPARE(w.heatmapPanel()->colormap(), Colormap::BlueRed);
    QCOMPARE(w.heatmapPanel()->range(), (std::pair<double, double>{-0.1, 0.1}));
    w.heatmapPanel()->setSharedScale(false);
    QVERIFY(settle(w, [&] { return w.heatmapPanel()->range().first != -0.1; }));
    QCOMPARE(w.heatmapPanel()->range().first, -w.heatmapPanel()->range().second);
    w.heatmapPanel()->setSharedScale(true);
    QCOMPARE(w.canvas()->layout(), ImageCanvas::Layout::Single);
    QCOMPARE(w.canvas()->current(), w.paneIndex(Source::Heatmap));
    // HDR-FLIP's map of A against B: core's, in magma over [0, 1].
    w.heatmapPanel()->setFlip();
    QVERIFY(settle(w, [&] { return w.heatmapPanel()->map() && w.heatmapPanel()->title().startsWith("HDR-FLIP"); }));
    QCOMPARE(maxAbsDiff(*w.heatmapPanel()->map(), metrics::hdr_flip(*results[0].image, *results[1].image).map, 1), 0.0);
    QCOMPARE(w.heatmapPanel()->colormap(), Colormap::Magma);
    QCOMPARE(w.heatmapPanel()->range(), (std::pair<double, double>{0.0, 1.0}));
    // Of A against the reference: the map the Results tab computed for its column, the same as core's.
    w.heatmapPanel()->setOf(HeatmapPanel::Of::A);
    QVERIFY(settle(w, [&] { return w.heatmapPanel()->map() && !w.heatmapPanel()->title().contains("against"); }));
    QCOMPARE(maxAbsDiff(*w.heatmapPanel()->map(),
                        metrics::hdr_flip(*w.session()->denoised(), w.session()->stack()->reference->image).map, 1),
             0.0);
    w.heatmapPanel()->setOf(HeatmapPanel::Of::AgainstB);
    w.heatmapPanel()->setKind(metrics::MapKind::RelativeSquaredError);

    // Removing a result drops its row; removing A makes the newest A.
    w.session()->removeResult(results[0].id);
    QCOMPARE(w.session()->results().size(), size_t(1));
    QCOMPARE(w.session()->a(), w.session()->results()[0].id);
    QCOMPARE(w.session()->b(), -1);
  }

  // The Pixel panel lists every result by name, A and B marked, with its values there (issue 53, item 10).
  void thePixelPanelNamesEveryResult() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    runModel(w, "tiny");
    runModel(w, "small");
    const auto& results = w.session()->results();
    QCOMPARE(results.size(), size_t(2));
    w.session()->setA(results[1].id);
    w.session()->setB(results[0].id);
    const QString text = PixelInspector::lines(*w.session(), QPoint(10, 20), nullptr, {}).join('\n');
    const auto values = [](const Image& img) {
      QStringList v;
      for (int c = 0; c < 3; ++c) v << QString::number(double(img.at(10, 20, c)), 'g', 6);
      return v.join(' ');
    };
    QVERIFY2(text.contains("A small fp32: " + values(*w.session()->denoised())), qPrintable(text));
    QVERIFY2(text.contains("B tiny fp32: " + values(*results[0].image)), qPrintable(text));
  }

  void heatmapsShareOneRangeAcrossResults() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    runModel(w, "tiny");
    runModel(w, "small");
    QVERIFY(w.heatmapPanel()->sharedScale());
    const auto range = HeatmapPanel::sharedRange(w.heatmapPanel()->kind());
    QVERIFY(settle(w, [&] { return w.heatmapPanel()->map() != nullptr; }));
    QCOMPARE(w.heatmapPanel()->range(), range);
    const QImage small_map = w.heatmapPanel()->image();
    QTest::keyClick(&w, Qt::Key_1);  // tiny as A
    QVERIFY(settle(w, [&] { return w.heatmapPanel()->title().contains("tiny"); }));
    QCOMPARE(w.heatmapPanel()->range(), range);
    // The heatmap pane is titled with the map it shows (it once kept the previous result's title).
    QVERIFY(settle(w, [&] { return w.paneIndex(Source::Heatmap) >= 0; }));
    QCOMPARE(w.canvas()->panes()[static_cast<size_t>(w.paneIndex(Source::Heatmap))].label, w.heatmapPanel()->title());
    QVERIFY(w.heatmapPanel()->title().contains("tiny fp32"));
    // Same range, so a pixel where both errors are equal-ish has the same colour; everywhere, the colour is
    // the shared scale's colour of that pixel's value.
    const Image& map = *w.heatmapPanel()->map();
    ColorScale sc;
    sc.log = true;
    sc.lo = range.first;
    sc.hi = range.second;
    QCOMPARE(w.heatmapPanel()->image(), colorize(map, w.heatmapPanel()->colormap(), sc));
    QVERIFY(small_map != w.heatmapPanel()->image());
    // Its own range: the map's extremes.
    w.heatmapPanel()->setSharedScale(false);
    QVERIFY(settle(w, [&] { return w.heatmapPanel()->range() != range; }));
    ColorScale own;
    own.log = true;
    QCOMPARE(w.heatmapPanel()->range(), resolve_range(map, own));
    // The histogram counts the map's values within the range.
    const auto* hist = w.heatmapPanel()->findChild<Histogram*>("histogram");
    QVERIFY(hist);
    int64_t total = hist->counts().below + hist->counts().above + hist->counts().invalid;
    for (auto c : hist->counts().bins) total += c;
    QCOMPARE(total, map.width() * map.height());
  }

  void filesAddedAsResultsAreScoredAndChecked() {
    QTemporaryDir dir;
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    const auto stack = w.session()->stack();
    // Another denoiser's output: here core's tiny, written as a plain RGB EXR.
    const Image other = denoise(*stack, nn::load_model(nn::find_model_for("tiny", feature_set_for(*stack))), {});
    writeRgb(dir.filePath("nfor.exr"), other);
    Image wrong(100, 80, 3);
    writeRgb(dir.filePath("small.exr"), wrong);
    w.addResultFiles({dir.filePath("nfor.exr")});
    QVERIFY(settle(w, [&] { return w.session()->results().size() == 1; }));
    const Result& r = w.session()->results()[0];
    QCOMPARE(r.name, QString("nfor.exr"));
    QVERIFY(r.fromFile());
    QCOMPARE(w.session()->a(), r.id);  // the first result becomes A
    QCOMPARE(maxAbsDiff(*r.image, other, 3), 0.0);
    QVERIFY(settle(w, [&] { return row(w.metricsPanel()->report(), "nfor.exr") != nullptr; }));
    QCOMPARE(row(w.metricsPanel()->report(), "nfor.exr")->scores.relmse,
             metrics::compare(other, stack->reference->image).relmse);
    // An image of another size is refused with the file and both sizes named.
    QSignalSpy failed(w.session(), &Session::resultFailed);
    w.addResultFiles({dir.filePath("small.exr")});
    QVERIFY(failed.wait(10000));
    const QString message = failed.at(0).at(0).toString();
    QVERIFY2(message.contains("small.exr") && message.contains("100 x 80") && message.contains("192 x 192"),
             qPrintable(message));
    QCOMPARE(w.session()->results().size(), size_t(1));
    // A second file becomes B.
    writeRgb(dir.filePath("colleague.exr"), stack->reference->image);
    w.addResultFiles({dir.filePath("colleague.exr")});
    QVERIFY(settle(w, [&] { return w.session()->results().size() == 2; }));
    QCOMPARE(w.session()->b(), w.session()->results()[1].id);
  }

  void exportAllWritesEverythingAndReplacesNothing() {
    QTemporaryDir dir;
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    runModel(w, "tiny");
    runModel(w, "small");
    QVERIFY(settle(w, [&] { return w.metricsPanel()->wholeReport().rows.size() == 3; }));
    const QString out = dir.filePath("export");
    auto f = w.exportAll(out, false);
    f.waitForFinished();
    QCOMPARE(f.result(), QString());
    const auto& results = w.session()->results();
    const auto stack = w.session()->stack();
    for (const auto& r : results) {
      const QString stem = file_stem(r.name);
      QCOMPARE(stem, QString(r.name).replace(' ', '_'));
      // The EXR: the result's pixels (half) and what made it.
      const Image back = readExr(out + "/" + stem + ".exr");
      QCOMPARE(back.width(), int64_t(192));
      double worst = 0;  // half floats: 11 significant bits
      for (int64_t i = 0; i < back.width() * back.height() * 3; ++i)
        worst = std::max(worst, std::abs(double(back.data()[i]) - double(r.image->data()[i])) /
                                    (std::abs(double(r.image->data()[i])) + 1e-3));
      QVERIFY2(worst < 1e-3, qPrintable(QString::number(worst)));
      auto in = OIIO::ImageInput::open((out + "/" + stem + ".exr").toStdString());
      QCOMPARE(QString::fromStdString(in->spec().get_string_attribute("residue:result")), r.name);
      // What ran, as residue-cli records it (core's provenance_of): the model by name, its architecture, the
      // backend and the post-steps; not the viewer's free-text description.
      const std::string model = in->spec().get_string_attribute("residue:model");
      QVERIFY2(model == "tiny" || model == "small", model.c_str());
      QVERIFY(!in->spec().get_string_attribute("residue:architecture").empty());
      QVERIFY(!in->spec().get_string_attribute("residue:backend").empty());
      QVERIFY(in->spec().find_attribute("residue:energy_correction") != nullptr);
      // The map's values, and its picture with the bar below.
      const Image map = readExr(out + "/heatmap-" + stem + ".exr");
      QCOMPARE(maxAbsDiff(map, metrics::error_map(*r.image, stack->reference->image, metrics::MapKind::RelativeSquaredError), 1), 0.0);
      const QImage png(out + "/heatmap-" + stem + ".png");
      QCOMPARE(png.height(), 192 + 64);
    }
    std::ifstream js((out + "/metrics.json").toStdString());
    const auto j = nlohmann::json::parse(js);
    QCOMPARE(j["rows"].size(), size_t(3));
    QCOMPARE(j["rows"][2]["name"].get<std::string>(), std::string("small fp32"));
    // Each row names the image it scored: the render, and each run's EXR written beside (not its description).
    QCOMPARE(j["rows"][0]["test_file"].get<std::string>(), stack->color.source.file);
    QCOMPARE(j["rows"][2]["test_file"].get<std::string>(), (out + "/small_fp32.exr").toStdString());
    QVERIFY(QFileInfo::exists(out + "/metrics.csv"));
    const QImage sheet(out + "/comparison.png");
    QVERIFY(sheet.width() > 2 * 192 && sheet.height() > 192);  // noisy, two results, reference: 4 images
    // Again, without permission to replace: refused, naming what is there, and nothing changes.
    const auto before = std::filesystem::last_write_time((out + "/metrics.json").toStdString());
    f = w.exportAll(out, false);
    f.waitForFinished();
    QVERIFY2(f.result().contains("metrics.json"), qPrintable(f.result()));
    QCOMPARE(std::filesystem::last_write_time((out + "/metrics.json").toStdString()), before);
    f = w.exportAll(out, true);
    f.waitForFinished();
    QCOMPARE(f.result(), QString());
  }

  void controllerRunsWithoutAWidget() {
    Session session;
    QSignalSpy loaded(&session, &Session::loaded);
    LoadOptions o;
    o.reference = kExample / "reference.exr";
    session.open({kExample / "noisy.exr"}, o);
    QVERIFY(loaded.wait(30000));
    std::vector<nn::ModelCard> models = nn::list_model_cards();
    DenoiseController c(&session, models);
    DenoiseController::Request r;
    r.model = "small";
    r.tile = 64;
    QSignalSpy finished(&c, &DenoiseController::finished);
    QSignalSpy progressed(&c, &DenoiseController::progressed);
    QVERIFY(c.start(r));
    QVERIFY(c.running());
    QVERIFY(!c.start(r));  // one at a time
    QVERIFY(QTest::qWaitFor([&] { return finished.count() == 1; }, 60000));
    QVERIFY(finished.at(0).at(0).toBool());
    QVERIFY(!progressed.isEmpty());
    QCOMPARE(progressed.last().at(1).toLongLong(), int64_t(9));  // 192 px in 64-px tiles
    QVERIFY(c.measuredSecondsPerMp("small").has_value());
    // Kept for the next start of the viewer on this CPU (issue 53, item 4).
    QCOMPARE(DenoiseController(&session, models).measuredSecondsPerMp("small"), c.measuredSecondsPerMp("small"));
    const Result* res = session.result(session.a());
    QVERIFY(res && res->complete && res->done());
    QCOMPARE(res->key, DenoiseController::key(r));
    // Equal to core's denoise with the same settings.
    DenoiseOptions core_options;
    core_options.tile = 64;
    const auto stack = session.stack();
    const Image expected = denoise(*stack, nn::load_model(nn::find_model_for("small", feature_set_for(*stack))), core_options);
    QVERIFY(maxAbsDiff(*res->image, expected, 3) < 1e-4);
    // The same request again: kept, no run; another precision: a new result.
    QVERIFY(!c.start(r));
    QCOMPARE(finished.count(), 2);
    QCOMPARE(session.results().size(), size_t(1));
    r.precision = nn::Precision::BF16;
    QCOMPARE(DenoiseController::name(r), QString("small bf16"));
    QVERIFY(DenoiseController::key(r) != res->key);
    DenoiseController::Request x8 = r;
    x8.ensemble = 8;
    QCOMPARE(DenoiseController::name(x8), QString("small bf16 x8"));
    QVERIFY(DenoiseController::key(x8) != DenoiseController::key(r));
    {
      // Another run, cancelled at its first tile so that it cannot finish first: fp32 without the energy
      // correction (a new key), which every CPU runs (bf16 needs AVX512_BF16 or AMX).
      DenoiseController::Request raw = r;
      raw.precision = nn::Precision::FP32;
      raw.energy_correction = false;
      HeldAtFirstTile held(&c);
      QVERIFY(c.start(raw));
      QVERIFY(held.reached());
      c.cancel();
    }
    QVERIFY(QTest::qWaitFor([&] { return finished.count() == 3; }, 60000));
    QCOMPARE(session.results().size(), size_t(2));
    // Cancelled: kept in the list, said so, never taken for a finished run.
    const Result* cancelled = session.result(session.a());
    QVERIFY(cancelled->state == RunState::Cancelled && cancelled->stateText.startsWith("cancelled"));
    QVERIFY(!cancelled->complete);
    // A self-ensemble: its own result, equal to core's with the same members.
    DenoiseController::Request x2;
    x2.model = "small";
    x2.tile = 64;
    x2.ensemble = 2;
    QVERIFY(c.start(x2));
    QVERIFY(QTest::qWaitFor([&] { return finished.count() == 4; }, 60000));
    QVERIFY(finished.last().at(0).toBool());
    QVERIFY(session.result(session.a())->description.contains("self-ensemble x2"));
    core_options.ensemble = 2;
    const Image expected_x2 = denoise(*stack, nn::load_model(nn::find_model_for("small", feature_set_for(*stack))), core_options);
    QVERIFY(maxAbsDiff(*session.result(session.a())->image, expected_x2, 3) < 1e-4);
    QVERIFY(maxAbsDiff(expected_x2, expected, 3) > 1e-3);  // the members changed the image
    // An alias (resources/models/aliases.json): `best` runs multiscale as a self-ensemble x8 unless told otherwise.
    DenoiseController::Request best;
    best.model = "best";
    best.tile = 64;
    QVERIFY(c.start(best));
    QVERIFY(QTest::qWaitFor([&] { return finished.count() == 5; }, 120000));
    QVERIFY(finished.last().at(0).toBool());
    QVERIFY2(session.result(session.a())->description.contains("self-ensemble x8"),
             qPrintable(session.result(session.a())->description));
    QVERIFY(session.result(session.a())->description.startsWith("multiscale"));
    // An unknown model is refused with a message.
    r.model = "nonesuch";
    QVERIFY(!c.start(r));
    QCOMPARE(finished.last().at(0).toBool(), false);
  }

  void windowFitsA1280x720Screen() {
    MainWindow w;
    w.setInteractive(false);
    w.resize(1280, 720);
    w.show();
    openExample(w);
    QVERIFY(QTest::qWaitForWindowExposed(&w));
    QVERIFY2(w.minimumSizeHint().width() <= 1280 && w.minimumSizeHint().height() <= 720,
             qPrintable(QString("%1 x %2").arg(w.minimumSizeHint().width()).arg(w.minimumSizeHint().height())));
    QCOMPARE(w.size(), QSize(1280, 720));
    // Canvas first: the image area takes most of the width.
    QVERIFY2(w.canvas()->width() > 1280 * 55 / 100, qPrintable(QString::number(w.canvas()->width())));
    // Fit follows the panes: a single pane is shown larger than four.
    QVERIFY(settle(w, [&] { return w.canvas()->panes().size() == 4; }));
    const double four = w.canvas()->zoom();
    w.setLayout(ImageCanvas::Layout::Single);
    QVERIFY(w.canvas()->zoom() > four * 1.5);
    // The shortcut overlay fits the canvas: every row is drawn inside it (two columns when one is too tall).
    w.activateWindow();
    QVERIFY(QTest::qWaitForWindowActive(&w));
    QTest::keyClick(&w, Qt::Key_F1);
    auto* help = w.canvas()->findChild<QWidget*>("helpOverlay");
    QVERIFY(help && help->isVisible());
    QCOMPARE(help->size(), w.canvas()->size());
    const QImage shot = help->grab().toImage();
    if (qEnvironmentVariableIsSet("RESIDUE_TEST_SHOTS")) shot.save(qEnvironmentVariable("RESIDUE_TEST_SHOTS") + "/help.png");
    int lowest = 0;  // the lowest row with yellow key text
    for (int y = 0; y < shot.height(); ++y)
      for (int x = 0; x < shot.width(); x += 2)
        if (const QColor c = shot.pixelColor(x, y); c.red() > 200 && c.green() > 170 && c.blue() < 140) lowest = y;
    QVERIFY2(lowest > 0 && lowest < shot.height() - 4, qPrintable(QString::number(lowest)));
    // ... and every description whole, at 1280x720 with the side bar shown (issue 53, item 11).
    const auto plan = static_cast<HelpOverlay*>(help)->plan();
    QVERIFY2(!plan.shortened, qPrintable(QString("%1 columns of %2 px, %3 pt").arg(plan.columns).arg(plan.column_width)
                                             .arg(plan.font.pointSizeF())));
    QTest::keyClick(&w, Qt::Key_Escape);
    QVERIFY(!help->isVisible());
    // The side bar can be closed (F9) for the whole window.
    QTest::keyClick(&w, Qt::Key_F9);
    QVERIFY(!w.findChild<QDockWidget*>("sideDock")->isVisible());
  }

  void pieces() {
    // Histogram counts against a plain count.
    Image v(10, 1, 1);
    for (int i = 0; i < 10; ++i) v.at(i, 0, 0) = static_cast<float>(i);
    v.at(9, 0, 0) = std::numeric_limits<float>::quiet_NaN();
    const auto h = histogram_counts(v, 1.0, 8.0, false, 7);
    QCOMPARE(h.below, int64_t(1));
    QCOMPARE(h.invalid, int64_t(1));
    QCOMPARE(h.above, int64_t(0));
    QCOMPARE(h.bins, (std::vector<int64_t>{1, 1, 1, 1, 1, 1, 2}));
    const auto hl = histogram_counts(v, 1.0, 100.0, true, 2);  // 1..10 | 10..100
    QCOMPARE(hl.bins, (std::vector<int64_t>{8, 0}));
    QCOMPARE(hl.below, int64_t(1));
    // File stems.
    QCOMPARE(file_stem("small fp32 (2)"), QString("small_fp32_2"));
    QCOMPARE(file_stem("../x"), QString(".._x"));
    QCOMPARE(file_stem("///"), QString("result"));
    QCOMPARE(file_stem("nfor.exr"), QString("nfor"));  // an added file's extension is not doubled
    QCOMPARE(file_stem("Beauty.EXR"), QString("Beauty"));
    QCOMPARE(file_stem(".exr"), QString(".exr"));
    // The sheet: 5 panels go 3 + 2, each labelled above and scored below.
    std::vector<SheetPanel> panels(5);
    for (auto& p : panels) {
      p.image = QImage(100, 50, QImage::Format_RGB32);
      p.image.fill(Qt::red);
      p.lines = {"relMSE 0.1"};
    }
    SheetOptions o;
    o.max_edge = 0;
    const QImage sheet = comparison_sheet(panels, o);
    QVERIFY(sheet.width() >= 3 * 200 && sheet.width() < 4 * 200);
    QCOMPARE(sheet.pixel(16 + 50, 16 + QFontMetrics(QFont()).height()), QColor(Qt::white).rgb());
    // With a region (issue 53, item 5): each panel's region outlined, its pixels under the image enlarged by a
    // whole factor (20 x 10 -> 200 x 100 in a 200-px cell: every pixel a 10 x 10 block), and its scores.
    for (auto& p : panels) {
      p.region = QRect(10, 5, 20, 10);
      p.detail = QImage(20, 10, QImage::Format_RGB32);
      p.detail.fill(Qt::blue);
      p.detail_lines = {"region relMSE 0.2"};
    }
    const QImage with_region = comparison_sheet(panels, o);
    QVERIFY(with_region.height() >= sheet.height() + 2 * 100);
    int blue = 0, yellow = 0;
    for (int y = 0; y < with_region.height(); ++y)
      for (int x = 0; x < with_region.width(); ++x) {
        const QRgb c = with_region.pixel(x, y);
        blue += c == QColor(Qt::blue).rgb();
        yellow += qRed(c) > 200 && qGreen(c) > 180 && qBlue(c) < 80;
      }
    QCOMPARE(blue, 5 * 200 * 100);
    QVERIFY(yellow > 5 * 2 * (20 + 10));  // the outlines
    // Depth is shown near-bright over its 1st-99th percentile; variance as its standard deviation.
    Image depth(100, 1, 1), var(100, 1, 3);
    for (int i = 0; i < 100; ++i) {
      depth.at(i, 0, 0) = i < 99 ? 1.0f + static_cast<float>(i) / 98.0f : 1e6f;  // one far miss
      for (int c = 0; c < 3; ++c) var.at(i, 0, c) = static_cast<float>(i * i) * 1e-6f;
    }
    const Image d = data_aov_for_display(depth, AovRole::Depth);
    QVERIFY(d.at(0, 0, 0) > 0.95f && d.at(98, 0, 0) < 0.05f);
    QVERIFY(std::abs(d.at(49, 0, 0) - 0.5f) < 0.05f);  // the miss does not squeeze the rest into one grey
    const Image s = data_aov_for_display(var, AovRole::Variance);
    QVERIFY(std::abs(s.at(49, 0, 0) - 0.5f) < 0.02f);
    // Motion (to the previous frame) as colour: red right, green down, grey still, blue constant.
    Image motion(100, 1, 4);
    for (int i = 0; i < 100; ++i) motion.at(i, 0, 0) = i == 0 ? -2.0f : i < 50 ? 2.0f : 0.0f, motion.at(i, 0, 1) = i == 1 ? 2.0f : 0.0f;
    const Image m = data_aov_for_display(motion, AovRole::Motion);
    QCOMPARE(m.channels(), 3);
    QVERIFY(m.at(0, 0, 0) < 0.2f && m.at(10, 0, 0) > 0.8f && std::abs(m.at(60, 0, 0) - 0.5f) < 1e-6f);
    QVERIFY(m.at(1, 0, 1) > 0.8f && std::abs(m.at(60, 0, 1) - 0.5f) < 1e-6f);
    QCOMPARE(m.at(10, 0, 2), 0.5f);
  }
};

QTEST_MAIN(TestResults)
#include "test_results.moc"
