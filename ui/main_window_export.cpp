// MainWindow's exports: the denoised EXR, the heatmap, the comparison sheet, the metrics and "export all". Each
// gathers what it needs on the UI thread and writes on a worker (runExport reports the result in the status bar).
#include <QDir>
#include <QFileDialog>
#include <QFileInfo>
#include <QFutureWatcher>
#include <QMessageBox>
#include <QSettings>
#include <QStatusBar>
#include <QtConcurrent/QtConcurrentRun>

#include "core/io/map_writer.h"
#include "core/io/metrics_report.h"
#include "ui/comparison_sheet.h"
#include "ui/denoise_panel.h"
#include "ui/export_all.h"
#include "ui/main_window.h"
#include "ui/metrics_panel.h"

namespace residue::ui {

namespace {
QString errorText(const std::exception& e) { return QString::fromStdString(e.what()); }
}  // namespace

QString MainWindow::askSavePath(const QString& title, const QString& filter, const QString& suffix) {
  QFileDialog dlg(this, title, startFolder(), filter);
  dlg.setAcceptMode(QFileDialog::AcceptSave);
  dlg.setDefaultSuffix(suffix);
  // The dialog asks before replacing an existing file (ConfirmOverwrite is on by default).
  if (dlg.exec() != QDialog::Accepted || dlg.selectedFiles().isEmpty()) return {};
  return dlg.selectedFiles().front();
}

void MainWindow::runExport(const QString& what, QFuture<QString> future) {
  ++exports_running_;
  say(tr("Writing %1...").arg(what));
  auto* w = new QFutureWatcher<QString>(this);
  connect(w, &QFutureWatcherBase::finished, this, [this, w, what] {
    --exports_running_;
    const QString error = w->result();
    if (error.isEmpty()) say(tr("Wrote the %1").arg(what), 8000);
    else if (interactive_) QMessageBox::warning(this, tr("Export failed"), error);
    else say(error, 15000);
    w->deleteLater();
  });
  w->setFuture(future);
}

QFuture<QString> MainWindow::exportDenoisedExr(const QString& path, bool overwrite, bool half,
                                               const QString& compression) {
  const auto denoised = session_->denoisedShared();
  const auto stack = session_->stack();
  const Result* shown = session_->result(session_->a());
  const Result result = shown ? *shown : Result{};
  return QtConcurrent::run([=]() -> QString {
    if (!denoised || !stack) return tr("Nothing to export: no denoised image.");
    try {
      write_result_exr(path.toStdString(), *denoised, *stack, result, overwrite, half, compression.toStdString());
      return {};
    } catch (const std::exception& e) {
      return errorText(e);
    }
  });
}

QFuture<QString> MainWindow::exportHeatmap(const QString& path, bool overwrite) {
  const auto map = heatmap_->map();
  const QImage picture = heatmap_->imageWithBar();
  return QtConcurrent::run([=]() -> QString {
    if (!map) return tr("Nothing to export: no heatmap (it needs a reference).");
    try {
      if (path.endsWith(".exr", Qt::CaseInsensitive)) {
        io::write_map_exr(path.toStdString(), *map, overwrite);
      } else {
        write_png(path.toStdString(), picture, overwrite, "heatmap PNG");
      }
      return {};
    } catch (const std::exception& e) {
      return errorText(e);
    }
  });
}

// What a comparison sheet shows, gathered on the UI thread and drawn on a worker.
struct MainWindow::SheetInputs {
  struct Item {
    QString label;
    std::shared_ptr<const Image> image;
    QStringList lines;
    QStringList region_lines;
  };
  std::vector<Item> items;
  std::optional<Rect> roi;
  std::shared_ptr<const DisplayTransform> display;
  DisplaySettings settings;
  SheetOptions options;

  QImage draw() const {
    std::vector<SheetPanel> panels;
    for (const auto& it : items) {
      SheetPanel p{it.label, {}, it.lines, {}, {}, it.region_lines};
      try {
        if (it.image) p.image = display->render(*it.image, 0, 3, it.image->bounds(), settings, Encoding::SceneLinear);
        if (it.image && roi) {
          p.region = QRect(static_cast<int>(roi->x), static_cast<int>(roi->y), static_cast<int>(roi->width),
                           static_cast<int>(roi->height));
          p.detail = display->render(*it.image, 0, 3, *roi, settings, Encoding::SceneLinear);
        }
      } catch (const std::exception&) {
        // drawn as "(no image)"
      }
      panels.push_back(std::move(p));
    }
    return comparison_sheet(panels, options);
  }
};

MainWindow::SheetInputs MainWindow::sheetInputs() const {
  SheetInputs in;
  in.display = display_;
  in.settings = displaySettings();
  const auto stack = session_->stack();
  if (!stack) return in;
  const auto scores_in = [](const io::MetricsReport& report, const QString& name, const QString& prefix) {
    for (const auto& row : report.rows)
      if (QString::fromStdString(row.name) == name)
        return QStringList{QString("%1relMSE %2   SSIM %3").arg(prefix).arg(row.scores.relmse, 0, 'g', 4).arg(row.scores.ssim, 0, 'f', 4),
                           QString("%1PSNR %2 dB").arg(prefix).arg(row.scores.psnr, 0, 'f', 2)};
    return QStringList{};
  };
  const auto& report = metrics_->wholeReport();
  const auto scores = [&](const QString& name) { return scores_in(report, name, QString()); };
  // With a region: each image's region enlarged under it, with the region's scores.
  in.roi = canvas_->roi();
  const auto region = [&](const QString& name) {
    return in.roi ? scores_in(metrics_->report(), name, tr("region ")) : QStringList{};
  };
  in.items.push_back({tr("Noisy input"), shared(Source::Noisy), scores("noisy"), region("noisy")});
  for (const auto& r : session_->results()) {
    const QString name = session_->resultName(r.id);
    QStringList lines = scores(name);
    if (r.seconds > 0 && !lines.isEmpty()) lines.back() += tr("   %1 s here").arg(r.seconds, 0, 'f', 2);
    else if (r.seconds > 0) lines << tr("%1 s here").arg(r.seconds, 0, 'f', 2);
    if (!r.done()) lines << r.stateText;
    in.items.push_back({name, r.image, lines, region(name)});
  }
  if (const auto ref = shared(Source::Reference)) in.items.push_back({tr("Reference"), ref, {}, {}});
  in.options.title = tr("%1   %2 x %3   reference: %4   display: %5 / %6, %7 EV")
                         .arg(session_->title())
                         .arg(stack->width())
                         .arg(stack->height())
                         .arg(stack->reference ? QFileInfo(QString::fromStdString(stack->reference->source.file)).fileName()
                                               : tr("none"))
                         .arg(QString::fromStdString(in.settings.display), QString::fromStdString(in.settings.view))
                         .arg(in.settings.exposure, 0, 'f', 1);
  return in;
}

QFuture<QString> MainWindow::exportComparison(const QString& path, bool overwrite) {
  const SheetInputs in = sheetInputs();
  return QtConcurrent::run([=]() -> QString {
    try {
      const QImage sheet = in.draw();
      if (sheet.isNull()) return tr("Nothing to export: no render open.");
      write_png(path.toStdString(), sheet, overwrite, "comparison PNG");
      return {};
    } catch (const std::exception& e) {
      return errorText(e);
    }
  });
}

QFuture<QString> MainWindow::exportMetrics(const QString& path, bool overwrite) {
  const io::MetricsReport report = metrics_->report();
  return QtConcurrent::run([=]() -> QString {
    if (report.rows.empty()) return tr("Nothing to export: no metrics (they need a reference).");
    try {
      io::write_metrics(path.toStdString(), report, overwrite);
      return {};
    } catch (const std::exception& e) {
      return errorText(e);
    }
  });
}

QFuture<QString> MainWindow::exportAll(const QString& folder, bool overwrite, bool region) {
  if (region && !canvas_->roi())
    return QtFuture::makeReadyFuture(tr("No region to export: drag one first (Shift+drag or right-drag)."));
  ExportAllInputs in;
  if (region) in.crop = canvas_->roi();
  in.stack = session_->stack();
  const int running = denoise_->controller()->runningResult();
  for (const auto& r : session_->results())
    if (r.id != running && !(r.atStrength() && r.base == running)) in.results.push_back(r);
  in.reference = shared(Source::Reference);
  in.options = metrics_->options();
  in.make_map = heatmap_->mapMaker(metrics_->options());
  in.map_name = heatmap_->title().section(" of ", 0, 0);
  in.colormap = heatmap_->colormap();
  in.scale = heatmap_->scale();
  in.whole = metrics_->wholeReport();
  if (canvas_->roi()) in.roi = metrics_->report();
  const SheetInputs sheet = sheetInputs();
  in.sheet = [sheet] { return sheet.draw(); };
  const std::filesystem::path dir = folder.toStdString();
  return QtConcurrent::run([in, dir, overwrite]() { return export_all(in, dir, overwrite); });
}

QFuture<QString> MainWindow::exportView(const QString& path, bool overwrite) {
  const QImage view = canvas_->grab().toImage();  // what the canvas shows, at its size
  const std::filesystem::path p = path.toStdString();
  return QtConcurrent::run([view, p, overwrite]() -> QString {
    try {
      write_png(p, view, overwrite, "view PNG");
      return {};
    } catch (const std::exception& e) {
      return QString::fromStdString(e.what());
    }
  });
}

void MainWindow::exportAllDialog(bool region) {
  const QString title = region ? tr("Export the Region") : tr("Export All");
  if (!session_->hasStack()) return void(QMessageBox::information(this, title, tr("Open a render first.")));
  if (region && !canvas_->roi())
    return void(QMessageBox::information(this, title, tr("Drag a region first (Shift+drag or right-drag).")));
  QSettings settings;
  const QString start = settings.value("exportFolder", QDir::homePath() + "/residue-export").toString();
  const QString folder = QFileDialog::getExistingDirectory(this, region ? tr("Export the region into a folder")
                                                                        : tr("Export all into a folder"),
                                                           QFileInfo(start).exists() ? start : QDir::homePath());
  if (folder.isEmpty()) return;
  settings.setValue("exportFolder", folder);
  // Ask once before replacing anything.
  ExportAllInputs probe;
  probe.stack = session_->stack();
  probe.results = session_->results();
  probe.reference = shared(Source::Reference);
  probe.whole = metrics_->wholeReport();
  if (canvas_->roi()) probe.roi = metrics_->report();
  if (region) probe.crop = canvas_->roi();
  probe.sheet = [] { return QImage(); };
  QStringList existing;
  for (const auto& f : planned_files(probe, folder.toStdString()))
    if (std::filesystem::exists(f)) existing << QString::fromStdString(f.filename().string());
  bool overwrite = false;
  if (!existing.isEmpty()) {
    if (QMessageBox::question(this, title,
                              tr("%1 already holds %n of these file(s):\n%2\n\nReplace them?", nullptr,
                                 static_cast<int>(existing.size()))
                                  .arg(folder, existing.mid(0, 12).join("\n") + (existing.size() > 12 ? "\n..." : "")),
                              QMessageBox::Yes | QMessageBox::Cancel, QMessageBox::Cancel) != QMessageBox::Yes)
      return;
    overwrite = true;
  }
  runExport(tr("export into %1").arg(folder), exportAll(folder, overwrite, region));
}

}  // namespace residue::ui
