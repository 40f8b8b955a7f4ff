// The viewer, driven headless (QT_QPA_PLATFORM=offscreen) the way a user drives it: open a real multilayer EXR,
// check what was mapped, set a ROI and compare the metrics shown with core's, denoise through the UI action,
// cancel one, export and read the files back.
#include <QAction>
#include <QApplication>
#include <QComboBox>
#include <QDir>
#include <QDoubleSpinBox>
#include <QFile>
#include <QFileInfo>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QMenu>
#include <QPalette>
#include <QPushButton>
#include <QSettings>
#include <QSignalSpy>
#include <QSlider>
#include <QStandardPaths>
#include <QStatusBar>
#include <QTableWidget>
#include <QTemporaryDir>
#include <QtTest>
#include <map>
#include <QWheelEvent>
#include <OpenImageIO/imageio.h>
#include <cmath>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/strength.h"
#include "core/features/features.h"
#include "core/image/colormap.h"
#include "core/metrics/flip.h"
#include "core/metrics/metrics.h"
#include "core/nn/model_registry.h"
#include "support/exr_fixture.h"
#include "ui/canvas.h"
#include "ui/histogram.h"
#include "ui/render_list.h"
#include "ui/denoise_panel.h"
#include "ui/heatmap_panel.h"
#include "ui/main_window.h"
#include "viewer_test_support.h"
#include "ui/mapping_dialog.h"
#include "ui/metrics_panel.h"
#include "ui/pixel_inspector.h"

using namespace residue;
using namespace residue::ui;
using namespace residue::ui::viewer_test;

namespace {

QAction* findAction(QWidget& w, const QKeySequence& shortcut) {
  for (QAction* a : w.findChildren<QAction*>())
    if (a->shortcut() == shortcut) return a;
  return nullptr;
}


}  // namespace

class TestViewer : public QObject {
  Q_OBJECT
 private slots:
  void initTestCase() {
    QStandardPaths::setTestModeEnabled(true);  // QSettings (recent files, mappings) in a test location
    QSettings().clear();
  }

  // The help overlay lists the actions' own shortcuts: a key bound without a line there fails here, and no key is
  // bound twice.
  void everyKeyIsInTheHelpAndBoundOnce() {
    MainWindow w;
    std::map<QString, QString> bound;  // key -> the action it runs
    for (const QAction* a : w.actions())
      for (const QKeySequence& k : a->shortcuts()) {
        QVERIFY2(!a->property("help").toString().isEmpty(), qPrintable(a->text() + " (" + k.toString() + ") is not in the help"));
        const auto [it, fresh] = bound.emplace(k.toString(), a->text());
        QVERIFY2(fresh, qPrintable(k.toString() + " runs both " + it->second + " and " + a->text()));
      }
    QVERIFY(bound.count("Left") && bound.count("P") && bound.count("Ctrl+Shift+D"));
  }

  // The README's key table lists every key the viewer binds, as its menus write it (issue 53: "the README's viewer
  // section matches what the viewer does, key by key").
  void theReadmeListsEveryKey() {
    std::ifstream file(std::filesystem::path(RESIDUE_SOURCE_RESOURCES).parent_path() / "README.md");
    QVERIFY(file);
    std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
    const QString readme = QString::fromStdString(text);
    const qsizetype start = readme.indexOf("| keys | |");
    QVERIFY(start >= 0);
    const QString table = readme.mid(start, readme.indexOf("\n\n", start) - start);
    MainWindow w;
    for (const QAction* a : w.actions()) {
      if (a->property("help").toString().isEmpty()) continue;
      QString keys = a->property("helpKeys").toString();
      if (keys.isEmpty()) keys = a->shortcut().toString(QKeySequence::NativeText);
      for (const QString& key : keys.split("  ", Qt::SkipEmptyParts))
        QVERIFY2(table.contains(key), qPrintable(key + " (" + a->text() + ") is not in the README's key table"));
    }
  }

  void opensMultilayerExrAndMapsAovs() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    const auto stack = w.session()->stack();
    QCOMPARE(stack->convention, std::string("Blender Cycles"));
    QVERIFY(stack->albedo && stack->normal && stack->depth && stack->reference);
    QCOMPARE(stack->color.source.layer, std::string("ViewLayer.Combined"));
    QCOMPARE(stack->albedo->source.layer, std::string("ViewLayer.Denoising Albedo"));
    QCOMPARE(stack->normal->source.layer, std::string("ViewLayer.Denoising Normal"));
    QCOMPARE(stack->width(), int64_t(192));
    // Noisy, denoised (empty until a denoise), reference and the heatmap pane.
    QVERIFY(settle(w, [&] { return w.canvas()->panes().size() == 4; }));
    const auto& panes = w.canvas()->panes();
    QVERIFY(!panes[0].display.isNull());
    QVERIFY(panes[1].display.isNull());
    QVERIFY(!panes[2].display.isNull());
    QCOMPARE(panes[0].display.size(), QSize(192, 192));
    // The inspector reads the stack's linear values.
    const QStringList lines = PixelInspector::lines(*w.session(), QPoint(10, 20), nullptr, {});
    QVERIFY(lines.join('\n').contains(QString::number(double(stack->color.image.at(10, 20, 0)), 'g', 6)));
    QVERIFY(lines.join('\n').contains("depth: "));
  }

  void roiMetricsEqualCore() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    const Rect roi{40, 30, 64, 50};
    w.setRoi(roi);
    QVERIFY(settle(w, [&] { return w.metricsPanel()->report().options.roi.has_value(); }));
    const auto& report = w.metricsPanel()->report();
    QCOMPARE(report.rows.size(), size_t(1));  // noisy only: nothing denoised yet
    metrics::Options o;
    o.roi = roi;
    const auto stack = w.session()->stack();
    const auto expected = metrics::compare(stack->color.image, stack->reference->image, o);
    QCOMPARE(report.rows[0].scores.relmse, expected.relmse);
    QCOMPARE(report.rows[0].scores.ssim, expected.ssim);
    QCOMPARE(report.rows[0].scores.pixels, roi.area());
    // What the table shows is that number.
    auto* table = w.metricsPanel()->findChild<QTableWidget*>("metricsTable");
    QVERIFY(table);
    int roi_column = -1;
    for (int c = 0; c < table->columnCount(); ++c)
      if (table->horizontalHeaderItem(c)->text() == "ROI relMSE") roi_column = c;
    QVERIFY(roi_column >= 0 && !table->isColumnHidden(roi_column));
    QCOMPARE(table->item(0, roi_column)->text(), QString::number(expected.relmse, 'g', 5));
    // HDR-FLIP, after the other scores: core's, over the whole image and averaged over the region.
    QVERIFY(settle(w, [&] { return w.metricsPanel()->report().rows[0].hdr_flip.has_value(); }));
    const metrics::FlipResult flip = metrics::hdr_flip(stack->color.image, stack->reference->image);
    QCOMPARE(*w.metricsPanel()->wholeReport().rows[0].hdr_flip, flip.mean);
    QCOMPARE(*w.metricsPanel()->report().rows[0].hdr_flip, metrics::flip_mean(flip.map, roi));
    QVERIFY(w.metricsPanel()->report().flip && w.metricsPanel()->report().flip->count == flip.exposures.count);
    int flip_column = -1;
    for (int c = 0; c < table->columnCount(); ++c)
      if (table->horizontalHeaderItem(c)->text() == "HDR-FLIP") flip_column = c;
    QVERIFY(flip_column >= 0 && !table->isColumnHidden(flip_column));
    QCOMPARE(table->item(0, flip_column)->text(), QString::number(flip.mean, 'g', 4));
    // The ROI differs from the whole image, and clearing it brings the whole image back.
    const auto whole = metrics::compare(stack->color.image, stack->reference->image);
    QVERIFY(std::abs(whole.relmse - expected.relmse) > 1e-6);
    w.setRoi(std::nullopt);
    QVERIFY(settle(w, [&] { return !w.metricsPanel()->report().options.roi; }));
    QCOMPARE(w.metricsPanel()->report().rows[0].scores.relmse, whole.relmse);
    // The eps setting is used.
    auto* eps = w.metricsPanel()->findChild<QDoubleSpinBox*>("metricsEps");
    eps->setValue(0.1);
    QVERIFY(settle(w, [&] { return w.metricsPanel()->report().options.eps == 0.1; }));
    metrics::Options o2;
    o2.eps = 0.1;
    QCOMPARE(w.metricsPanel()->report().rows[0].scores.relmse,
             metrics::compare(stack->color.image, stack->reference->image, o2).relmse);
  }

  void denoiseThroughTheUiEqualsCore() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    QVERIFY(w.denoisePanel()->selectModel("tiny"));
    QSignalSpy finished(w.denoisePanel(), &DenoisePanel::finished);
    QAction* action = findAction(w, QKeySequence(Qt::CTRL | Qt::Key_D));
    QVERIFY(action);
    QCOMPARE(action->text().remove('&'), QString("Denoise"));
    action->trigger();
    QVERIFY(settle(w, [&] { return finished.count() == 1; }));
    QCOMPARE(finished.at(0).at(0).toBool(), true);
    const Image* denoised = w.session()->denoised();
    QVERIFY(denoised);
    // The same denoise through core directly.
    const auto stack = w.session()->stack();
    const auto model = nn::load_model(nn::find_model_for("tiny", feature_set_for(*stack)));
    const Image expected = denoise(*stack, model, {});
    QVERIFY2(maxAbsDiff(*denoised, expected, 3) < 1e-4, "UI denoise differs from core's");
    // Metrics now have a denoised row, better than the noisy one, equal to core's.
    QVERIFY(settle(w, [&] { return w.metricsPanel()->report().rows.size() == 2; }));
    const auto& rows = w.metricsPanel()->report().rows;
    QCOMPARE(rows[1].scores.relmse, metrics::compare(*denoised, stack->reference->image).relmse);
    QVERIFY(rows[1].scores.relmse < rows[0].scores.relmse / 4);
    // The canvas shows it, and the heatmap is the rse map of the denoised image.
    QVERIFY(!w.canvas()->panes()[1].display.isNull());
    QVERIFY(settle(w, [&] { return w.heatmapPanel()->map() != nullptr; }));
    const Image rse = metrics::error_map(*denoised, stack->reference->image, metrics::MapKind::RelativeSquaredError);
    QCOMPARE(maxAbsDiff(*w.heatmapPanel()->map(), rse, 1), 0.0);
    // The status bar reads the pane under the cursor: the denoised values over the denoised pane, the noisy
    // ones over the noisy pane.
    auto* cursor = w.findChild<QLabel*>("cursorLabel");
    QVERIFY(cursor);
    for (int pane : {0, 1}) {
      const QRect r = w.canvas()->paneRects()[static_cast<size_t>(pane)];
      QTest::mouseMove(w.canvas(), r.center());
      const auto pixel = w.canvas()->pixelAt(r.center());
      QVERIFY(pixel);
      const Image& shown = pane == 0 ? stack->color.image : *denoised;
      const QString expected_value = QString::number(static_cast<double>(shown.at(pixel->x(), pixel->y(), 0)), 'g', 4);
      QVERIFY2(cursor->text().contains(pane == 0 ? "Noisy " : "A: tiny fp32") && cursor->text().contains(expected_value),
               qPrintable(cursor->text() + " / expected " + expected_value));
    }

    // Asking again for the same model is served from the cache, without a job.
    QSignalSpy again(w.denoisePanel(), &DenoisePanel::finished);
    w.denoisePanel()->start();
    QCOMPARE(again.count(), 1);
    QVERIFY(!w.denoisePanel()->running());
  }

  // The Strength slider makes a result of its own beside the full one, at once and without a run (issue 53,
  // item 7): moving it re-blends that one, 100 % takes it away, and the full result is never touched.
  void strengthMakesAResultBesideTheFullOne() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    runModel(w, "tiny");
    const auto stack = w.session()->stack();
    const int full_id = w.session()->a();
    const QString full_name = w.session()->resultName(full_id);
    const Image full = *w.session()->denoised();
    auto* slider = w.denoisePanel()->findChild<QSlider*>("strength");
    QVERIFY(slider);
    slider->setValue(50);
    QVERIFY(!w.denoisePanel()->running());
    QCOMPARE(w.session()->results().size(), size_t(2));
    const int half_id = w.session()->a();
    QVERIFY(half_id != full_id);
    QCOMPARE(w.session()->resultName(half_id), full_name + " @ 50 %");
    QCOMPARE(maxAbsDiff(*w.session()->denoised(), with_strength(stack->color.image, full, 0.5f), 3), 0.0);
    QCOMPARE(maxAbsDiff(*w.session()->result(full_id)->image, full, 3), 0.0);
    QVERIFY(w.session()->denoisedDescription().endsWith("strength 0.50"));
    // Each is scored as what it is.
    QVERIFY(settle(w, [&] {
      const auto& rows = w.metricsPanel()->report().rows;
      return rows.size() == 3 &&
             rows[1].scores.relmse == metrics::compare(full, stack->reference->image).relmse &&
             rows[2].scores.relmse == metrics::compare(*w.session()->denoised(), stack->reference->image).relmse;
    }));
    // Moving on re-blends the same one.
    slider->setValue(0);
    QCOMPARE(w.session()->a(), half_id);
    QCOMPARE(w.session()->results().size(), size_t(2));
    QCOMPARE(w.session()->resultName(half_id), full_name + " @ 0 %");
    QCOMPARE(maxAbsDiff(*w.session()->denoised(), stack->color.image, 3), 0.0);
    // Picking the full result shows it at 100 %; the slider then makes a second blend beside the first.
    w.session()->setA(full_id);
    QCOMPARE(slider->value(), 100);
    slider->setValue(75);
    QCOMPARE(w.session()->results().size(), size_t(3));
    QCOMPARE(w.session()->resultName(w.session()->a()), full_name + " @ 75 %");
    w.session()->setA(half_id);
    QCOMPARE(slider->value(), 0);  // the slider shows A's strength
    // Back to 100 %: that blend goes, and the full result is A again, untouched.
    slider->setValue(100);
    QCOMPARE(w.session()->results().size(), size_t(2));
    QCOMPARE(w.session()->a(), full_id);
    QCOMPARE(maxAbsDiff(*w.session()->denoised(), full, 3), 0.0);
    // An export at 25 % writes what is shown and says so.
    slider->setValue(25);
    QTemporaryDir dir;
    const QString path = dir.filePath("d.exr");
    auto future = w.exportDenoisedExr(path, false, false, "zip");
    future.waitForFinished();
    QVERIFY2(future.result().isEmpty(), qPrintable(future.result()));
    QCOMPARE(maxAbsDiff(readExr(path), with_strength(stack->color.image, full, 0.25f), 3), 0.0);
    auto in = OIIO::ImageInput::open(path.toStdString());
    QVERIFY(in);
    QCOMPARE(in->spec().get_float_attribute("residue:strength", -1.0f), 0.25f);
    // Removing the full result takes its blends with it.
    w.session()->removeResult(full_id);
    QVERIFY(w.session()->results().empty());
  }

  // Issue 53, item 2: with a region, a result's name and its region scores are visible together, at 1280x720
  // and at 1920x1080, and the name keeps the width it needs.
  void regionScoresSitBesideTheNames() {
    for (const QSize size : {QSize(1280, 720), QSize(1920, 1080)}) {
      MainWindow w;
      w.setInteractive(false);
      w.resize(size);
      w.show();
      openExample(w);
      runModel(w, "tiny");
      w.showSideTab(MainWindow::SideTab::Results);
      w.setRoi(Rect{40, 30, 64, 50});
      QVERIFY(settle(w, [&] { return w.metricsPanel()->report().options.roi.has_value(); }));
      auto* table = w.metricsPanel()->findChild<QTableWidget*>("metricsTable");
      QVERIFY(table);
      std::map<QString, int> columns;
      for (int c = 0; c < table->columnCount(); ++c) columns[table->horizontalHeaderItem(c)->text()] = c;
      const int viewport = table->viewport()->width();
      const QFontMetrics fm(table->font());
      for (const QString& name : {QString("result"), QString("ROI relMSE"), QString("ROI SSIM")}) {
        const int c = columns.at(name);
        const int x = table->columnViewportPosition(c);
        QVERIFY2(!table->isColumnHidden(c) && x >= 0 && x + table->columnWidth(c) <= viewport,
                 qPrintable(QString("%1 at %2 + %3 of %4 px").arg(name).arg(x).arg(table->columnWidth(c)).arg(viewport)));
      }
      int tiny_row = -1;
      for (int r = 0; r < table->rowCount(); ++r)
        if (table->item(r, columns.at("result"))->text().startsWith("tiny")) tiny_row = r;
      QVERIFY(tiny_row >= 0);
      const QString name = table->item(tiny_row, columns.at("result"))->text();
      QVERIFY2(fm.horizontalAdvance(name) + 8 <= table->columnWidth(columns.at("result")),
               qPrintable(name + " in " + QString::number(table->columnWidth(columns.at("result"))) + " px"));
    }
  }

  // Issue 53, item 4: the status bar and the Pixel panel read what is under the mouse after a flip, a layout change
  // or a zoom, without waiting for the mouse to move.
  void statusFollowsTheViewUnderAStillMouse() {
    MainWindow w;
    w.setInteractive(false);
    w.resize(1280, 720);
    w.show();
    openExample(w);
    runModel(w, "tiny");
    auto* cursor = w.findChild<QLabel*>("cursorLabel");
    QVERIFY(cursor);
    w.canvas()->setLayout(ImageCanvas::Layout::Single);
    w.canvas()->setWipePair(0, 1);
    w.canvas()->setCurrent(0);
    const QPoint centre = w.canvas()->paneRects().front().center();
    QTest::mouseMove(w.canvas(), centre);
    QVERIFY2(cursor->text().contains("Noisy"), qPrintable(cursor->text()));
    QTest::keyClick(w.canvas(), Qt::Key_Space);  // flip to A, the mouse where it was
    QVERIFY2(cursor->text().contains("A: tiny fp32"), qPrintable(cursor->text()));
    auto* inspector = w.findChild<PixelInspector*>();
    QVERIFY(inspector);
    const auto before = w.canvas()->pixelAt(centre);
    w.canvas()->zoomAbout(4.0, QPointF(centre) + QPointF(40, 30));  // the pixel under the mouse moves
    const auto after = w.canvas()->pixelAt(centre);
    QVERIFY(before && after && *before != *after);
    QVERIFY2(cursor->text().startsWith(QString("x %1  y %2").arg(after->x()).arg(after->y())), qPrintable(cursor->text()));
    QCOMPARE(inspector->text(), PixelInspector::lines(*w.session(), *after, w.heatmapPanel()->map().get(),
                                                      w.heatmapPanel()->title()).join('\n'));
  }

  void roiDenoiseRunsOnlyTheRoi() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    QVERIFY(w.denoisePanel()->selectModel("tiny"));
    const Rect roi{64, 64, 48, 40};
    w.setRoi(roi);
    w.denoisePanel()->setRoiOnly(true);
    QSignalSpy finished(w.denoisePanel(), &DenoisePanel::finished);
    w.denoisePanel()->start();
    QVERIFY(settle(w, [&] { return finished.count() == 1; }));
    const auto stack = w.session()->stack();
    const Image* d = w.session()->denoised();
    QVERIFY(d);
    // Outside the ROI: the noisy input; inside: core's ROI denoise.
    QCOMPARE(d->at(5, 5, 0), stack->color.image.at(5, 5, 0));
    DenoiseOptions o;
    o.roi = roi;
    const Image expected = denoise(*stack, nn::load_model(nn::find_model("tiny")), o);
    QVERIFY(maxAbsDiff(*d, expected, 3) < 1e-4);
  }

  void cancelStopsEarlyAndKeepsInput() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    QVERIFY(w.denoisePanel()->selectModel("small"));
    w.denoisePanel()->setTile(64);  // 9 tiles
    QSignalSpy finished(w.denoisePanel(), &DenoisePanel::finished);
    // The run is held at its first tile while it is cancelled, then let go: it stops at the next tile.
    HeldAtFirstTile held(w.denoisePanel()->controller());
    w.denoisePanel()->start();
    QVERIFY(w.denoisePanel()->running());
    QVERIFY(held.reached());
    w.denoisePanel()->cancel();
    held.release();
    QVERIFY(settle(w, [&] { return finished.count() == 1; }));
    QCOMPARE(finished.at(0).at(0).toBool(), false);
    QVERIFY(finished.at(0).at(1).toString().contains("cancelled"));
    QVERIFY2(finished.at(0).at(1).toString().contains("after 1 of 9 tiles"), qPrintable(finished.at(0).at(1).toString()));
    // The last tile row was never reached: it still shows the noisy input.
    const auto stack = w.session()->stack();
    const Image* d = w.session()->denoised();
    QVERIFY(d);
    QCOMPARE(d->at(150, 180, 1), stack->color.image.at(150, 180, 1));
    // Its row says it was cancelled, where the name cannot elide it away, and has no scores (issue 53, item 3).
    QVERIFY(settle(w, [&] { return !w.metricsPanel()->busy(); }));
    auto* table = w.metricsPanel()->findChild<QTableWidget*>("metricsTable");
    int row = -1, name = -1, relmse = -1;
    for (int c = 0; c < table->columnCount(); ++c) {
      if (table->horizontalHeaderItem(c)->text() == "result") name = c;
      if (table->horizontalHeaderItem(c)->text() == "relMSE") relmse = c;
    }
    for (int r = 0; r < table->rowCount(); ++r)
      if (table->item(r, name)->text().startsWith("small")) row = r;
    QVERIFY(row >= 0);
    QVERIFY2(table->item(row, name)->text().endsWith("(cancelled)"), qPrintable(table->item(row, name)->text()));
    QVERIFY(table->item(row, name)->toolTip().startsWith("cancelled after 1 of 9 tiles"));
    QCOMPARE(table->item(row, relmse)->text(), QString("-"));
    QCOMPARE(w.metricsPanel()->wholeReport().rows.size(), size_t(1));  // only the noisy input is scored
    // The Denoise tab says so too, and no longer shows the progress it had (tile n of m, time left).
    const QString status = w.denoisePanel()->findChild<QLabel*>("denoiseStatus")->text();
    QVERIFY2(status.contains("cancelled after 1 of 9 tiles") && !status.contains("left"), qPrintable(status));
    // A cancelled run is not cached: the next run denoises (and finishes).
    QSignalSpy again(w.denoisePanel(), &DenoisePanel::finished);
    w.denoisePanel()->start();
    QVERIFY(settle(w, [&] { return again.count() == 1; }));
    QCOMPARE(again.at(0).at(0).toBool(), true);
    QVERIFY(w.session()->denoised()->at(150, 180, 1) != stack->color.image.at(150, 180, 1));
  }

  void exportsReadBackAndNeverOverwrite() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    QVERIFY(w.denoisePanel()->selectModel("tiny"));
    QSignalSpy finished(w.denoisePanel(), &DenoisePanel::finished);
    w.denoisePanel()->start();
    QVERIFY(settle(w, [&] { return finished.count() == 1 && w.heatmapPanel()->map(); }));
    QTemporaryDir dir;
    const auto path = [&](const char* name) { return dir.filePath(name); };

    // Denoised EXR, float: bit-exact round trip, with the source's metadata and ours.
    auto f = w.exportDenoisedExr(path("den.exr"), false, /*half=*/false, "zip");
    f.waitForFinished();
    QCOMPARE(f.result(), QString());
    const Image back = readExr(path("den.exr"));
    QCOMPARE(back.width(), int64_t(192));
    QCOMPARE(maxAbsDiff(back, *w.session()->denoised(), 3), 0.0);
    auto in = OIIO::ImageInput::open(path("den.exr").toStdString());
    QVERIFY(in);
    QVERIFY(in->spec().get_string_attribute("residue:model").find("tiny") != std::string::npos);
    in.reset();
    // Never replaced without asking: the file is unchanged and the error says why.
    std::ofstream(path("keep.exr").toStdString()) << "mine";
    f = w.exportDenoisedExr(path("keep.exr"), false);
    f.waitForFinished();
    QVERIFY(f.result().contains("keep.exr"));
    std::ifstream keep(path("keep.exr").toStdString());
    std::string content;
    keep >> content;
    QCOMPARE(content, std::string("mine"));

    // Heatmap PNG: the colormap bytes core gives for the map, with the colour bar below; heatmap EXR: the values.
    f = w.exportHeatmap(path("heat.png"), false);
    f.waitForFinished();
    QCOMPARE(f.result(), QString());
    QImage png(path("heat.png"));
    QCOMPARE(png.height(), 192 + 64);
    QVERIFY(png.width() >= 192);
    const QImage expected = colorize(*w.heatmapPanel()->map(), w.heatmapPanel()->colormap(), w.heatmapPanel()->scale());
    QCOMPARE(png.convertToFormat(QImage::Format_RGB32).copy(0, 0, 192, 192), expected);
    // The bar under it runs from the colormap's first colour to its last.
    const auto first = colormap_lookup(w.heatmapPanel()->colormap(), 0.0);
    const auto last = colormap_lookup(w.heatmapPanel()->colormap(), 1.0);
    const int bar_y = 192 + 4 + QFontMetrics(QFont()).height() + 8;
    QVERIFY(bar_y < png.height());
    const QRgb left = png.pixel(4, std::min(bar_y, png.height() - 20)), right = png.pixel(png.width() - 5, std::min(bar_y, png.height() - 20));
    QCOMPARE(qRed(left), int(first[0]));
    QCOMPARE(qBlue(right), int(last[2]));
    f = w.exportHeatmap(path("heat.exr"), false);
    f.waitForFinished();
    QCOMPARE(f.result(), QString());
    QCOMPARE(maxAbsDiff(readExr(path("heat.exr")), *w.heatmapPanel()->map(), 1), 0.0);

    // Metrics JSON: the numbers shown.
    f = w.exportMetrics(path("m.json"), false);
    f.waitForFinished();
    QCOMPARE(f.result(), QString());
    std::ifstream js(path("m.json").toStdString());
    const auto j = nlohmann::json::parse(js);
    QCOMPARE(j["rows"].size(), size_t(2));
    QCOMPARE(j["rows"][1]["name"].get<std::string>(), std::string("tiny fp32"));
    QCOMPARE(j["rows"][1]["relmse"].get<double>(), w.metricsPanel()->report().rows[1].scores.relmse);
    f = w.exportMetrics(path("m.csv"), false);
    f.waitForFinished();
    QCOMPARE(f.result(), QString());
    QVERIFY(QFile(path("m.csv")).size() > 50);

    // The comparison sheet: noisy, tiny and the reference at 1:1 (192 px), in one row on white.
    f = w.exportComparison(path("cmp.png"), false);
    f.waitForFinished();
    QCOMPARE(f.result(), QString());
    const QImage sheet(path("cmp.png"));
    QVERIFY2(sheet.width() >= 3 * 200 && sheet.width() < 4 * 200 && sheet.height() > 192 && sheet.height() < 2 * 192,
             qPrintable(QString("%1 x %2").arg(sheet.width()).arg(sheet.height())));
    QCOMPARE(sheet.pixel(2, 2), QColor(Qt::white).rgb());
  }

  // Keys typed into a field are the field's (issue 53, item 8): Tab moves on from the eps box instead of switching
  // panes, and digits typed into the heatmap's range go into it instead of picking results.
  void keysTypedIntoAFieldAreTheFields() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    QVERIFY(QTest::qWaitForWindowExposed(&w));
    openExample(w);
    w.setLayout(ImageCanvas::Layout::Single);
    const int pane = w.canvas()->current();
    auto* eps = w.metricsPanel()->findChild<QDoubleSpinBox*>("metricsEps");
    w.activateWindow();
    eps->setFocus();
    QTRY_VERIFY(eps->hasFocus());
    QTest::keyClick(eps, Qt::Key_Tab);
    QCOMPARE(w.canvas()->current(), pane);
    QVERIFY(!eps->hasFocus());
    QTest::keyClick(&w, Qt::Key_Tab);  // outside a field, Tab still switches panes
    QVERIFY(w.canvas()->current() != pane);
    QLineEdit* hi = nullptr;
    for (auto* e : w.heatmapPanel()->findChildren<QLineEdit*>())
      if (!e->isReadOnly()) hi = e;
    QVERIFY(hi);
    hi->setFocus();
    QTRY_VERIFY(hi->hasFocus());
    QTest::keyClicks(hi, "0.5");
    QCOMPARE(hi->text(), QString("0.5"));
  }

  // The Denoise tab's "done in ..." is about the render it ran on: opening another clears it (issue 53, item 4).
  void theLastRunsStatusGoesWithItsRender() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    runModel(w, "tiny");
    auto* status = w.denoisePanel()->findChild<QLabel*>("denoiseStatus");
    QVERIFY2(status->text().contains("done in"), qPrintable(status->text()));
    openExample(w);
    QVERIFY2(status->text().isEmpty(), qPrintable(status->text()));
  }

  // Open Recent lists a render once however its path was written (relative or absolute, a folder with or without
  // "/"), tells alike files apart by their folder, and opens a render again with the reference it was compared
  // with (issue 53, item 13).
  void openRecentListsEachRenderOnceWithItsFolderAndReference() {
    QSettings().clear();
    QTemporaryDir dir;
    for (const char* folder : {"kitchen", "hall"}) {
      QVERIFY(QDir(dir.path()).mkpath(folder));
      QVERIFY(QFile::copy(QString::fromStdString((kExample / "noisy.exr").string()), dir.filePath(QString(folder) + "/noisy.exr")));
    }
    const QString kitchen = dir.filePath("kitchen/noisy.exr"), hall = dir.filePath("hall/noisy.exr");
    const QString reference = QString::fromStdString((kExample / "reference.exr").string());
    MainWindow w;
    w.setInteractive(false);
    w.show();
    const auto open = [&](const QString& file, const LoadOptions& o = {}) {
      w.openFiles({file}, o);
      QVERIFY(settle(w, [&] { return !w.session()->loading(); }));
    };
    open(QDir::current().relativeFilePath(kitchen));
    open(hall);
    open(dir.filePath("kitchen") + "/");
    open(dir.filePath("kitchen"));
    open(kitchen);
    auto* menu = w.findChild<QMenu*>("recentMenu");
    QVERIFY(menu);
    QStringList labels;
    for (const QAction* a : menu->actions()) labels << a->text();
    QCOMPARE(labels.size(), 3);  // kitchen/noisy.exr, the kitchen folder, hall/noisy.exr
    QVERIFY2(labels[0].startsWith("noisy.exr") && labels[0].contains("kitchen"), qPrintable(labels.join(" | ")));
    QVERIFY2(labels[1].startsWith("kitchen/"), qPrintable(labels.join(" | ")));
    QVERIFY2(labels[2].startsWith("noisy.exr") && labels[2].contains("hall"), qPrintable(labels.join(" | ")));

    // A reference opened after the render is remembered with it.
    QVERIFY(!w.session()->reference());
    w.openReferenceFile(reference);
    QVERIFY(settle(w, [&] { return w.session()->reference() != nullptr; }));
    open(hall);
    QVERIFY(!w.session()->reference());
    QAction* again = nullptr;
    for (QAction* a : menu->actions())
      if (a->text().contains("kitchen") && a->text().startsWith("noisy.exr")) again = a;
    QVERIFY(again && again->toolTip().contains("reference.exr"));
    again->trigger();
    QVERIFY(settle(w, [&] { return !w.session()->loading() && w.session()->reference(); }));
    QCOMPARE(QFileInfo(QString::fromStdString(w.session()->inputs().front().string())).canonicalFilePath(),
             QFileInfo(kitchen).canonicalFilePath());
  }

  // What the viewer remembers across restarts (issue 53, item 15), and that a window which never restored its
  // settings (a test, a screenshot) leaves them alone.
  void settingsAreKeptAcrossRestarts() {
    QSettings().clear();
    {
      MainWindow w;
      w.restoreSettings();
      w.show();
      w.setLayout(ImageCanvas::Layout::Wipe);
      w.setTheme(MainWindow::Theme::Dark);
      w.heatmapPanel()->setColormap(Colormap::Magma);
      w.heatmapPanel()->setLog(true);
      QVERIFY(w.denoisePanel()->selectModel("tiny"));
      w.resize(1000, 650);
      w.close();
    }
    {
      MainWindow w;
      w.restoreSettings();
      QCOMPARE(w.canvas()->layout(), ImageCanvas::Layout::Wipe);
      QCOMPARE(w.theme(), MainWindow::Theme::Dark);
      QVERIFY(QApplication::palette().color(QPalette::Window).lightness() < 80);
      QCOMPARE(w.heatmapPanel()->colormap(), Colormap::Magma);
      QVERIFY(w.heatmapPanel()->scale().log);
      QCOMPARE(w.denoisePanel()->selectedModel(), QString("tiny"));
      QCOMPARE(w.size(), QSize(1000, 650));
      w.setTheme(MainWindow::Theme::System);
      QVERIFY(QApplication::palette().color(QPalette::Window).lightness() > 150);
    }
    QSettings().clear();
    {
      MainWindow w;
      w.show();
      w.setLayout(ImageCanvas::Layout::Wipe);
      w.close();
    }
    QVERIFY(QSettings().allKeys().filter("viewer/").isEmpty());
  }

  // Every toolbar control is named by a label; the menus show the keys as they are typed (issue 53, item 14).
  void toolbarControlsAreLabelledAndMenusShowTheirKeys() {
    MainWindow w;
    for (const char* name : {"layoutBox", "aovBox", "exposureBox", "offsetBox", "displayBox", "viewBox"}) {
      auto* control = w.findChild<QWidget*>(name);
      QVERIFY(control);
      bool labelled = false;
      for (const QLabel* l : w.findChildren<QLabel*>()) labelled |= l->buddy() == control && !l->text().isEmpty();
      QVERIFY2(labelled, name);
    }
    QCOMPARE(w.findChild<QDoubleSpinBox*>("offsetBox")->prefix(), QString());  // "+ -0.010" read as a sum
    bool previous = false, cancel = false;
    for (const QAction* a : w.findChildren<QAction*>()) {
      if (a->text() == "Previous pane") previous = a->shortcut().toString() == "Shift+Tab";
      if (a->text().startsWith("&Cancel")) cancel = a->text().endsWith("\tEsc");
    }
    QVERIFY(previous && cancel);
  }

  // A status message wider than the bar is shortened in its middle, whole in the tooltip and statusText().
  void aLongStatusMessageIsShortenedInItsMiddle() {
    MainWindow w;
    w.setInteractive(false);
    w.resize(900, 600);
    w.show();
    const QString missing = QDir::temp().filePath(QString("deep/").repeated(40) + "no-such-render.exr");
    w.openFiles({missing});
    QVERIFY(settle(w, [&] { return !w.lastError().isEmpty(); }));
    QVERIFY2(w.statusText().contains("no-such-render.exr") && w.statusText().contains(QString("deep/").repeated(40)),
             qPrintable(w.statusText()));
    const QString shown = w.statusBar()->currentMessage();
    QVERIFY2(shown.size() < w.statusText().size() && shown.contains(QChar(0x2026)), qPrintable(shown));
    QVERIFY(shown.startsWith("Could not load"));
    QCOMPARE(w.statusBar()->toolTip(), w.statusText());
  }

  // Every render opened joins the image list with its own results, A and B, region and view; PgUp / PgDn step
  // through the list; opening a render already open shows it; a dropped image of another size is a new entry;
  // nothing that arrives replaces another render (issue 53, item 6).
  void rendersOpenedJoinTheImageList() {
    QTemporaryDir dir;
    const QString second = dir.filePath("second.exr");
    QVERIFY(QFile::copy(QString::fromStdString((kExample / "noisy.exr").string()), second));
    testing::FixturePart part;
    part.width = part.height = 40;
    for (const char* c : {"R", "G", "B"}) part.channels.push_back({c, false, [](int x, int) { return 0.01f * static_cast<float>(x); }});
    const QString small = dir.filePath("small.exr");
    testing::write_fixture_exr(small.toStdString(), {part});

    MainWindow w;
    w.setInteractive(false);
    w.resize(1280, 720);
    w.show();
    openExample(w);
    runModel(w, "tiny");
    const int tiny = w.session()->a();
    const Rect roi{10, 12, 50, 40};
    w.setRoi(roi);
    w.canvas()->setView(3.0, QPointF(60, 70));
    w.openFiles({second});
    QVERIFY(settle(w, [&] { return w.session()->renderCount() == 2 && w.session()->currentRender() == 1; }));
    QVERIFY(w.session()->results().empty());  // its own list
    QCOMPARE(w.session()->title(), QString("second.exr"));
    QVERIFY(w.windowTitle().contains("(2 of 2)"));
    w.setRoi(std::nullopt);
    runModel(w, "tiny");
    // Back to the first, as it was left.
    QTest::keyClick(&w, Qt::Key_PageUp);
    QVERIFY(settle(w, [&] { return w.session()->currentRender() == 0 && !w.canvas()->panes().empty(); }));
    QCOMPARE(w.session()->results().size(), size_t(1));
    QCOMPARE(w.session()->a(), tiny);
    QCOMPARE(w.canvas()->roi(), std::optional<Rect>(roi));
    QCOMPARE(w.canvas()->zoom(), 3.0);
    QCOMPARE(w.canvas()->center(), QPointF(60, 70));
    // The list says each render's result count.
    auto* items = w.renderList()->list();
    QCOMPARE(items->count(), 2);
    QVERIFY2(items->item(0)->text().contains("1 result"), qPrintable(items->item(0)->text()));
    if (qEnvironmentVariableIsSet("RESIDUE_TEST_SHOTS")) {
      w.showSideTab(MainWindow::SideTab::Renders);
      QVERIFY(settle(w, [] { return true; }));
      w.grab().save(qEnvironmentVariable("RESIDUE_TEST_SHOTS") + "/renders.png");
    }
    // Opening a render already open shows it, results and all.
    w.openFiles({second});
    QVERIFY(settle(w, [&] { return w.session()->currentRender() == 1; }));
    QCOMPARE(w.session()->renderCount(), 2);
    QCOMPARE(w.session()->results().size(), size_t(1));
    QVERIFY(!w.canvas()->roi());
    // A dropped image of another size is a render of its own, after the one shown.
    emit w.canvas()->filesDropped({small});
    QVERIFY(settle(w, [&] { return w.session()->renderCount() == 3 && w.session()->currentRender() == 2; }));
    QCOMPARE(w.session()->stack()->width(), int64_t{40});
    // Clicking an entry shows it; Ctrl+W closes the one shown and its neighbour is shown.
    items->setCurrentRow(0);
    QVERIFY(settle(w, [&] { return w.session()->currentRender() == 0; }));
    QTest::keyClick(&w, Qt::Key_W, Qt::ControlModifier);
    QVERIFY(settle(w, [&] { return w.session()->renderCount() == 2 && w.session()->hasStack(); }));
    QCOMPARE(w.session()->title(), QString("second.exr"));
    QCOMPARE(w.session()->results().size(), size_t(1));
    QTest::keyClick(&w, Qt::Key_W, Qt::ControlModifier);
    QTest::keyClick(&w, Qt::Key_W, Qt::ControlModifier);
    QVERIFY(settle(w, [&] { return w.session()->renderCount() == 0 && !w.session()->hasStack(); }));
    QVERIFY(w.canvas()->panes().empty());
    QCOMPARE(w.windowTitle(), QString("Residue"));
  }

  // Renders asked for while another is being opened wait for it instead of superseding it (the command line's
  // --open, a client's open requests): all of them join the list, in order, alike names told apart by folder.
  void rendersOpenedAtOnceAllJoin() {
    QTemporaryDir dir;
    QStringList files;
    for (const char* folder : {"a", "b", "c"}) {
      QVERIFY(QDir(dir.path()).mkpath(folder));
      files << dir.filePath(QString(folder) + "/noisy.exr");
      QVERIFY(QFile::copy(QString::fromStdString((kExample / "noisy.exr").string()), files.back()));
    }
    MainWindow w;
    w.setInteractive(false);
    w.show();
    w.openFiles({files[0]});
    w.openFiles({files[1]}, {}, false);
    w.openFiles({files[2]}, {}, false);
    QVERIFY(settle(w, [&] { return w.session()->renderCount() == 3; }));
    QCOMPARE(w.session()->currentRender(), 0);
    for (int i = 0; i < 3; ++i)
      QCOMPARE(QFileInfo(w.session()->renderInputs(i).front()).canonicalFilePath(), QFileInfo(files[i]).canonicalFilePath());
    auto* items = w.renderList()->list();
    QVERIFY2(items->item(1)->text().contains("(b)"), qPrintable(items->item(1)->text()));
  }

  // A run goes on into its own render while another is shown, and is found there finished.
  void aRunGoesOnWhileAnotherRenderIsShown() {
    QTemporaryDir dir;
    const QString second = dir.filePath("second.exr");
    QVERIFY(QFile::copy(QString::fromStdString((kExample / "noisy.exr").string()), second));
    MainWindow w;
    w.setInteractive(false);
    w.show();
    w.openFiles({second});
    QVERIFY(settle(w, [&] { return w.session()->hasStack(); }));
    openExample(w);
    QVERIFY(w.denoisePanel()->selectModel("tiny"));
    QSignalSpy finished(w.denoisePanel(), &DenoisePanel::finished);
    {
      HeldAtFirstTile held(w.denoisePanel()->controller());
      w.denoisePanel()->start();
      QVERIFY(held.reached());
      w.session()->showRender(0);  // second.exr, while the run is held
      QCOMPARE(w.session()->title(), QString("second.exr"));
    }
    QVERIFY(settle(w, [&] { return finished.count() == 1; }));
    QVERIFY2(finished.at(0).at(0).toBool(), qPrintable(finished.at(0).at(1).toString()));
    QVERIFY(w.session()->results().empty());  // second.exr has none
    w.session()->showRender(1);
    QVERIFY(settle(w, [&] { return w.session()->currentRender() == 1; }));
    QCOMPARE(w.session()->results().size(), size_t(1));
    const Result& run = w.session()->results().front();
    QVERIFY(run.done() && run.complete);
    const auto stack = w.session()->stack();
    QVERIFY(maxAbsDiff(*run.image, denoise(*stack, nn::load_model(nn::find_model("tiny")), DenoiseOptions{}), 3) < 1e-4);
  }

  // One pane shown stays the same image when B comes and its index moves (it used to jump to the reference).
  void theSinglePaneShownStaysWhenBArrives() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    runModel(w, "tiny");
    const int tiny = w.session()->a();
    runModel(w, "small");
    QVERIFY(settle(w, [&] { return w.paneIndex(Source::Heatmap) >= 0 && w.canvas()->panes().size() == 4; }));
    w.showPane(Source::Heatmap);
    QCOMPARE(w.canvas()->current(), 3);
    w.session()->setB(tiny);
    QVERIFY(settle(w, [&] { return w.canvas()->panes().size() == 5; }));
    QCOMPARE(w.paneIndex(Source::Heatmap), 4);
    QCOMPARE(w.canvas()->current(), 4);
    QCOMPARE(w.canvas()->layout(), ImageCanvas::Layout::Single);
  }

  // The region's export: each result's, the noisy input's and the reference's pixels there, written where they lie
  // in the frame, the maps cut to it, and the region's scores; the view as a PNG of the canvas (issue 53, item 18).
  void aRegionAndTheViewAreExported() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    runModel(w, "tiny");
    const Rect roi{40, 30, 64, 50};
    w.setRoi(roi);
    QVERIFY(settle(w, [&] { return w.metricsPanel()->report().options.roi == std::optional<Rect>(roi); }));
    QTemporaryDir dir;
    auto f = w.exportAll(dir.path(), false, true);
    f.waitForFinished();
    QCOMPARE(f.result(), QString());
    QVERIFY(!QFile::exists(dir.filePath("comparison.png")));
    const auto stack = w.session()->stack();
    const Image* result = w.session()->denoised();
    for (const auto& [file, full] : std::vector<std::pair<QString, const Image*>>{
             {"tiny_fp32.exr", result}, {"noisy.exr", &stack->color.image}, {"reference.exr", &stack->reference->image}}) {
      auto in = OIIO::ImageInput::open(dir.filePath(file).toStdString());
      QVERIFY2(in, qPrintable(file));
      const auto& spec = in->spec();
      QCOMPARE(std::vector<int>({spec.x, spec.y, spec.width, spec.height}), std::vector<int>({40, 30, 64, 50}));
      QCOMPARE(std::vector<int>({spec.full_width, spec.full_height}), std::vector<int>({192, 192}));
      in.reset();
      const Image back = readExr(dir.filePath(file));
      double worst = 0;  // half precision: 2^-11 relative
      for (int64_t y = 0; y < roi.height; ++y)
        for (int64_t x = 0; x < roi.width; ++x)
          for (int c = 0; c < 3; ++c) {
            const double want = full->at(roi.x + x, roi.y + y, c);
            worst = std::max(worst, std::abs(back.at(x, y, c) - want) / std::max(1e-3, std::abs(want)));
          }
      QVERIFY2(worst < 1e-3, qPrintable(file + ": " + QString::number(worst)));
    }
    QCOMPARE(readExr(dir.filePath("heatmap-tiny_fp32.exr")).width(), int64_t{64});
    std::ifstream json(dir.filePath("metrics.json").toStdString());
    const auto report = nlohmann::json::parse(json);
    metrics::Options o;
    o.roi = roi;
    const auto expected = metrics::compare(*result, stack->reference->image, o);
    bool found = false;
    for (const auto& row : report["rows"])
      if (row["name"] == "tiny fp32") {
        found = true;
        QCOMPARE(row["pixels"].get<int64_t>(), int64_t{64 * 50});
        QCOMPARE(row["relmse"].get<double>(), expected.relmse);
      }
    QVERIFY(found);
    // Again: nothing is replaced without asking.
    f = w.exportAll(dir.path(), false, true);
    f.waitForFinished();
    QVERIFY2(f.result().contains("tiny_fp32.exr"), qPrintable(f.result()));
    // The view: what the canvas shows, at its size; never over a file without asking.
    const QString view = dir.filePath("view.png");
    f = w.exportView(view, false);
    f.waitForFinished();
    QCOMPARE(f.result(), QString());
    QCOMPARE(QImage(view).size(), w.canvas()->size());
    f = w.exportView(view, false);
    f.waitForFinished();
    QVERIFY(!f.result().isEmpty());
  }

  // The Pixel tab's image histogram counts every pixel of the image under the cursor (else A, else the noisy
  // input) by its luminance, on a log axis (issue 53, item 17).
  void theImageHistogramCountsTheImageShown() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    QVERIFY(settle(w, [&] { return !w.canvas()->panes().empty(); }));
    const auto total = [&] {
      const auto& c = w.imageHistogram()->counts();
      int64_t n = c.below + c.above + c.invalid;
      for (int64_t b : c.bins) n += b;
      return n;
    };
    QCOMPARE(total(), int64_t{192 * 192});
    // Against a count made here: Rec. 709 luminance of the noisy colour, in the histogram's own bins.
    const auto stack = w.session()->stack();
    Image y(192, 192, 1);
    for (int64_t r = 0; r < 192; ++r)
      for (int64_t x = 0; x < 192; ++x)
        y.at(x, r, 0) = 0.2126f * stack->color.image.at(x, r, 0) + 0.7152f * stack->color.image.at(x, r, 1) +
                        0.0722f * stack->color.image.at(x, r, 2);
    ColorScale log;
    log.log = true;
    const auto range = resolve_range(y, log);
    const auto& shown = w.imageHistogram()->counts();
    const HistogramCounts expected = histogram_counts(y, range.first, range.second, true, static_cast<int>(shown.bins.size()));
    QCOMPARE(shown.bins, expected.bins);
    // A denoised result becomes A: its histogram is shown once the cursor is not over another pane.
    runModel(w, "tiny");
    QVERIFY(settle(w, [&] { return w.canvas()->panes().size() == 4; }));
    ColorScale log2;
    log2.log = true;
    Image ya(192, 192, 1);
    const Image& a = *w.session()->denoised();
    for (int64_t r = 0; r < 192; ++r)
      for (int64_t x = 0; x < 192; ++x)
        ya.at(x, r, 0) = 0.2126f * a.at(x, r, 0) + 0.7152f * a.at(x, r, 1) + 0.0722f * a.at(x, r, 2);
    const auto ra = resolve_range(ya, log2);
    QVERIFY(settle(w, [&] {
      return w.imageHistogram()->counts().bins ==
             histogram_counts(ya, ra.first, ra.second, true, static_cast<int>(shown.bins.size())).bins;
    }));
  }

  // A pixel's values, written in its cell at high zoom, fit the cell: fewer digits rather than a number running into
  // the next cell (issue 53, item 12).
  void valuesWrittenInACellFitIt() {
    QFont f;
    f.setPixelSize(9);
    const QFontMetrics fm(f);
    for (double v : {-0.000123456, 12345.678, 0.5, -1.0e-30, 3.0e38}) {
      const QString text = ImageCanvas::fittedValueText(v, ImageCanvas::kValueTextZoom - 4, fm);
      QVERIFY2(!text.isEmpty() && fm.horizontalAdvance(text) <= ImageCanvas::kValueTextZoom - 4, qPrintable(text));
      QVERIFY2(std::abs(text.toDouble() - v) <= std::abs(v) * 0.5, qPrintable(text));  // still the value, rounded
    }
    QCOMPARE(ImageCanvas::fittedValueText(0.5, 60, fm), QString("0.5"));
    QCOMPARE(ImageCanvas::fittedValueText(0.123456, 200, fm), QString("0.1235"));
    QVERIFY(ImageCanvas::fittedValueText(-0.000123456, 3, fm).isEmpty());
  }

  // The heatmap pane of a render without results says why it is empty, and never names the last render's result
  // (issue 53, item 4).
  void theHeatmapPlaceholderNamesOnlyWhatThisRenderHas() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    runModel(w, "tiny");
    const QString name = w.session()->resultName(w.session()->a());
    QVERIFY(!name.isEmpty());
    const auto heat = [&]() -> const Pane* {
      const int i = w.paneIndex(Source::Heatmap);
      return i < 0 ? nullptr : &w.canvas()->panes()[static_cast<size_t>(i)];
    };
    QVERIFY(settle(w, [&] { return heat() && !heat()->display.isNull(); }));
    QVERIFY2(heat()->label.contains(name), qPrintable(heat()->label));
    QTemporaryDir dir;  // another render: a copy of the example (the same file again would show the same render)
    const QString copy = dir.filePath("noisy.exr");
    QVERIFY(QFile::copy(QString::fromStdString((kExample / "noisy.exr").string()), copy));
    LoadOptions o;
    o.reference = kExample / "reference.exr";
    w.openFiles({copy}, o);
    QVERIFY(settle(w, [&] { return w.session()->currentRender() == 1 && w.session()->results().empty() && heat() &&
                                   heat()->display.isNull(); }));
    for (const QString& text : {heat()->label, heat()->placeholder})
      QVERIFY2(!text.contains(name), qPrintable(text + " names " + name));
    QVERIFY2(heat()->placeholder.contains("no result A yet"), qPrintable(heat()->placeholder));
  }

  // A region drawn on one render never reaches outside the next one (issue 53, item 1): it is clipped to a smaller
  // render, cleared when none of it is inside, and the whole image's scores are there either way.
  void aRegionIsClippedOrClearedWhenAnotherRenderOpens() {
    QTemporaryDir dir;
    const auto write = [&](const QString& name, float value) {
      testing::FixturePart part;
      part.width = part.height = 96;
      for (const char* c : {"R", "G", "B"})
        part.channels.push_back({c, false, [value](int x, int y) { return value + 0.002f * static_cast<float>((x * 7 + y * 3) % 40); }});
      testing::write_fixture_exr(dir.filePath(name).toStdString(), {part});
      return dir.filePath(name);
    };
    const QString small_ref = write("small_ref.exr", 0.25f);
    LoadOptions with_ref;
    with_ref.reference = small_ref.toStdString();
    // A new render each time (one already open would be shown as it was left, with its own region).
    const auto open_small = [&](MainWindow& w, const QString& name) {
      w.openFiles({write(name, 0.3f)}, with_ref);
      QVERIFY2(settle(w, [&] { return w.session()->hasStack() && w.session()->stack()->data_window.width == 96 &&
                                      !w.metricsPanel()->report().rows.empty(); }),
               qPrintable(w.lastError()));
    };
    const auto whole = [&](MainWindow& w) {
      const auto stack = w.session()->stack();
      return metrics::compare(stack->color.image, stack->reference->image).relmse;
    };

    MainWindow w;
    w.setInteractive(false);
    w.show();
    openExample(w);
    w.setRoi(Rect{40, 50, 100, 100});  // reaches x 140, y 150: past the 96 x 96 render
    open_small(w, "small.exr");
    QCOMPARE(w.canvas()->roi(), std::optional<Rect>(Rect{40, 50, 56, 46}));
    QVERIFY(settle(w, [&] { return w.metricsPanel()->report().options.roi == std::optional<Rect>(Rect{40, 50, 56, 46}); }));
    QCOMPARE(w.metricsPanel()->report().rows[0].scores.pixels, int64_t(56 * 46));
    QVERIFY2(w.statusText().contains("clipped"), qPrintable(w.statusText()));

    openExample(w);
    w.setRoi(Rect{120, 130, 50, 40});  // wholly outside the 96 x 96 render
    open_small(w, "small2.exr");
    QVERIFY(!w.canvas()->roi());
    QVERIFY(settle(w, [&] { return !w.metricsPanel()->report().options.roi; }));
    QCOMPARE(w.metricsPanel()->report().rows[0].scores.relmse, whole(w));
    QVERIFY2(w.statusText().contains("cleared"), qPrintable(w.statusText()));
    auto* table = w.metricsPanel()->findChild<QTableWidget*>("metricsTable");
    QVERIFY(table && table->rowCount() > 0);
    bool shown = false;  // the whole image's relMSE is in the table, not "..."
    for (int c = 0; c < table->columnCount(); ++c)
      if (table->item(0, c) && table->item(0, c)->text() == QString::number(whole(w), 'g', 5)) shown = true;
    QVERIFY(shown);
  }

  void unmappedChannelsGoThroughTheMappingDialogAndAreRemembered() {
    QTemporaryDir dir;
    const std::string file = dir.filePath("odd.exr").toStdString();
    testing::FixturePart part;
    part.width = part.height = 16;
    for (const char* c : {"beauty_r", "beauty_g", "beauty_b"}) part.channels.push_back(testing::constant_channel(c, 0.5f));
    for (const char* c : {"mystery.R", "mystery.G", "mystery.B"}) part.channels.push_back(testing::constant_channel(c, 0.25f));
    testing::write_fixture_exr(file, {part});

    MainWindow w;
    w.setInteractive(false);
    w.show();
    w.openFiles({QString::fromStdString(file)});
    QVERIFY(settle(w, [&] { return !w.lastError().isEmpty(); }));
    QVERIFY(!w.session()->hasStack());
    QVERIFY2(w.lastError().contains("odd.exr"), qPrintable(w.lastError()));

    MappingDialog dlg(file, w.lastError());
    QCOMPARE(dlg.channels().size(), 6);
    dlg.choose(AovRole::Color, {"mystery.R", "mystery.G", "mystery.B"});
    QCOMPARE(dlg.flags(), QStringList{"color=mystery.R,mystery.G,mystery.B"});
    remember_mapping(dlg.channels(), dlg.flags());

    // Opened again: the remembered mapping is applied without asking.
    w.openFiles({QString::fromStdString(file)});
    QVERIFY2(settle(w, [&] { return w.session()->hasStack(); }), qPrintable(w.lastError()));
    QCOMPARE(w.session()->stack()->color.image.at(3, 3, 0), 0.25f);
  }

  void mouseZoomPanAndRoi() {
    MainWindow w;
    w.setInteractive(false);
    w.resize(1400, 800);
    w.show();
    QVERIFY(QTest::qWaitForWindowExposed(&w));
    openExample(w);
    QVERIFY(settle(w, [&] { return w.canvas()->panes().size() == 4; }));
    ImageCanvas* c = w.canvas();
    const QRect pane = c->paneRects()[1];
    const QPoint at = pane.center() + QPoint(17, -9);
    const auto before = c->pixelAt(at);
    QVERIFY(before);
    // The wheel zooms about the cursor: the pixel under it stays under it, in every pane.
    QWheelEvent wheel(at, c->mapToGlobal(at), QPoint(), QPoint(0, 240), Qt::NoButton, Qt::NoModifier,
                      Qt::NoScrollPhase, false);
    QApplication::sendEvent(c, &wheel);
    QVERIFY(c->zoom() > 1.0);
    QCOMPARE(c->pixelAt(at), before);
    const QPoint same_in_noisy = c->paneRects()[0].topLeft() + (at - pane.topLeft());
    QCOMPARE(c->pixelAt(same_in_noisy), before);  // zoom and pan are locked together
    // A drag pans: the pixel under the cursor follows it.
    QTest::mousePress(c, Qt::LeftButton, Qt::NoModifier, at);
    QTest::mouseMove(c, at + QPoint(30, 0));
    QTest::mouseRelease(c, Qt::LeftButton, Qt::NoModifier, at + QPoint(30, 0));
    QCOMPARE(c->pixelAt(at + QPoint(30, 0)), before);
    // Shift+drag sets a region of interest, which scopes the metrics.
    c->fit();
    const QPoint a = pane.topLeft() + QPoint(pane.width() / 4, pane.height() / 2 - 20);
    const QPoint b = a + QPoint(40, 30);
    const auto pa = c->pixelAt(a), pb = c->pixelAt(b);
    QVERIFY(pa && pb);
    QTest::mousePress(c, Qt::LeftButton, Qt::ShiftModifier, a);
    QTest::mouseMove(c, b);
    QTest::mouseRelease(c, Qt::LeftButton, Qt::ShiftModifier, b);
    QVERIFY(c->roi());
    QVERIFY(std::abs(c->roi()->x - pa->x()) <= 1 && std::abs(c->roi()->y - pa->y()) <= 1);
    QVERIFY(std::abs(c->roi()->x + c->roi()->width - pb->x()) <= 1);
    QVERIFY(settle(w, [&] { return w.metricsPanel()->report().options.roi == c->roi(); }));
    QTest::keyClick(&w, Qt::Key_Backspace);
    QVERIFY(!c->roi());
    // ? shows the shortcut overlay, Esc hides it.
    auto* help = w.findChild<QWidget*>("helpOverlay");
    QVERIFY(help && !help->isVisible());
    QTest::keyClick(&w, Qt::Key_Question, Qt::ShiftModifier);
    QVERIFY(help->isVisible());
    QTest::keyClick(&w, Qt::Key_Escape);
    QVERIFY(!help->isVisible());
  }

  // Issue 53, item 16: every layer of the render's files can be looked at, not only the AOVs a denoise reads:
  // [ and ] page on from the AOVs to the layers no AOV took (the room's alpha, its unused Depth and Normal passes),
  // each shown with its own values; the layer stays shown when the render is read again; an AOV picked ends it.
  void everyLayerOfTheFileCanBeShown() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    QVERIFY(QTest::qWaitForWindowExposed(&w));
    openExample(w);
    QVERIFY(settle(w, [&] { return w.canvas()->panes().size() == 4; }));
    auto* box = w.findChild<QComboBox*>("aovBox");
    QVERIFY(box);
    for (const char* name : {"ViewLayer.Combined.A", "ViewLayer.Depth.Z", "ViewLayer.Normal"})
      QVERIFY2(box->findData(name, Qt::ToolTipRole) >= 0, name);
    QVERIFY(box->findText("Combined.A") >= 0);  // listed without the prefix every layer has
    QCOMPARE(w.session()->otherLayers().size(), size_t{3});
    // Colour, albedo, normal, depth, then (variance and motion absent, the separator skipped) the alpha.
    for (int k = 0; k < 4; ++k) QTest::keyClick(&w, Qt::Key_BracketRight);
    QCOMPARE(w.layer(), QString("ViewLayer.Combined.A"));
    QVERIFY(settle(w, [&] { return w.canvas()->panes()[0].label == "Noisy: ViewLayer.Combined.A"; }));

    // Its values, read here with OpenImageIO on their own.
    const auto channel_values = [](const std::string& channel) {
      auto in = OIIO::ImageInput::open((kExample / "noisy.exr").string());
      const auto& spec = in->spec();
      const int c = spec.channelindex(channel);
      std::vector<float> v(static_cast<size_t>(spec.width * spec.height));
      in->read_image(0, 0, c, c + 1, OIIO::TypeFloat, v.data());
      return std::make_pair(v, static_cast<int>(spec.width));
    };
    const auto expect_shown = [&](const std::string& channel) {
      const auto [values, width] = channel_values(channel);
      const auto shown = w.canvas()->panes()[0].values;
      QVERIFY(shown);
      QCOMPARE(shown->channels(), 1);
      for (const auto& [x, y] : {std::pair{0, 0}, {37, 11}, {width - 1, 20}})
        QCOMPARE(shown->at(x, y, 0), values[static_cast<size_t>(y * width + x)]);
    };
    expect_shown("ViewLayer.Combined.A");
    {  // An alpha is shown as it is (1 white), not through the view's tone curve.
      const auto [alpha, width] = channel_values("ViewLayer.Combined.A");
      QCOMPARE(alpha[0], 1.0f);
      QCOMPARE(qGray(w.canvas()->panes()[0].display.pixel(0, 0)), 255);
    }
    QVERIFY(w.setLayer("ViewLayer.Depth.Z"));
    QVERIFY(settle(w, [&] { return w.canvas()->panes()[0].label == "Noisy: ViewLayer.Depth.Z"; }));
    expect_shown("ViewLayer.Depth.Z");
    QVERIFY(!w.setLayer("ViewLayer.Emission"));
    QCOMPARE(w.layer(), QString("ViewLayer.Depth.Z"));

    w.session()->reload();
    QVERIFY(settle(w, [&] { return !w.session()->loading() && w.canvas()->panes().size() == 4; }));
    QCOMPARE(w.layer(), QString("ViewLayer.Depth.Z"));
    QVERIFY(settle(w, [&] { return w.canvas()->panes()[0].label == "Noisy: ViewLayer.Depth.Z"; }));
    expect_shown("ViewLayer.Depth.Z");

    w.setAov(AovRole::Albedo);
    QVERIFY(w.layer().isEmpty());
    QVERIFY(settle(w, [&] { return w.canvas()->panes()[0].label == "Noisy: Albedo"; }));
    QCOMPARE(w.canvas()->panes()[0].values->channels(), 3);
  }

  void keyboardDrivesTheView() {
    MainWindow w;
    w.setInteractive(false);
    w.show();
    QVERIFY(QTest::qWaitForWindowExposed(&w));
    openExample(w);
    QVERIFY(settle(w, [&] { return w.canvas()->panes().size() == 4; }));
    const QRgb before = w.canvas()->panes()[0].display.pixel(100, 100);
    QTest::keyClick(&w, Qt::Key_E);
    QCOMPARE(w.exposure(), 0.5);
    QVERIFY(settle(w, [&] { return w.canvas()->panes()[0].display.pixel(100, 100) != before; }));
    QVERIFY(qGray(w.canvas()->panes()[0].display.pixel(100, 100)) > qGray(before));
    QTest::keyClick(&w, Qt::Key_E, Qt::ShiftModifier);
    QCOMPARE(w.exposure(), 0.0);
    // Tab: one pane, then the next ones in turn.
    w.canvas()->setCurrent(0);
    for (int k = 0; k < 3; ++k) QTest::keyClick(&w, Qt::Key_Tab);
    QCOMPARE(w.canvas()->layout(), ImageCanvas::Layout::Single);
    QCOMPARE(w.canvas()->current(), w.paneIndex(Source::Reference));
    QTest::keyClick(&w, Qt::Key_W);
    QCOMPARE(w.canvas()->layout(), ImageCanvas::Layout::Wipe);
    QTest::keyClick(&w, Qt::Key_S);
    QCOMPARE(w.canvas()->layout(), ImageCanvas::Layout::Pair);
    QTest::keyClick(&w, Qt::Key_A);
    QCOMPARE(w.canvas()->layout(), ImageCanvas::Layout::SideBySide);
    QTest::keyClick(&w, Qt::Key_BracketRight);
    QCOMPARE(w.aov(), AovRole::Albedo);
    QTest::keyClick(&w, Qt::Key_BracketLeft);
    QCOMPARE(w.aov(), AovRole::Color);
    const double fit = w.canvas()->zoom();
    QTest::keyClick(&w, Qt::Key_Plus);  // half a stop (issue 53, item 15)
    QVERIFY(std::abs(w.canvas()->zoom() / fit - std::sqrt(2.0)) < 1e-9);
    QTest::keyClick(&w, Qt::Key_Minus);
    QVERIFY(std::abs(w.canvas()->zoom() / fit - 1.0) < 1e-9);
    QTest::keyClick(&w, Qt::Key_0, Qt::ControlModifier);
    QCOMPARE(w.canvas()->zoom(), 1.0);
    QTest::keyClick(&w, Qt::Key_F);
    QCOMPARE(w.canvas()->zoom(), fit);
  }
};

QTEST_MAIN(TestViewer)
#include "test_viewer.moc"
