#include "ui/main_window.h"

#include <QAction>
#include <QApplication>
#include <QCloseEvent>
#include <QComboBox>
#include <QDialog>
#include <QDialogButtonBox>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QFileSystemWatcher>
#include <QFormLayout>
#include <QKeyEvent>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <QSettings>
#include <QStandardItemModel>
#include <QStatusBar>
#include <QTimer>
#include <QToolBar>
#include <QtConcurrent/QtConcurrentRun>
#include <cmath>

#include "core/io/atomic_file.h"
#include "core/io/exr_writer.h"
#include "core/io/map_writer.h"
#include "core/io/metrics_report.h"
#include "core/util/error.h"
#include "ui/denoise_panel.h"
#include "ui/help_overlay.h"
#include "ui/mapping_dialog.h"
#include "ui/metrics_panel.h"
#include "ui/pane_renderer.h"
#include "ui/pixel_inspector.h"
#include "ui/tev_server.h"

namespace residue::ui {

namespace {
constexpr int kMaxRecent = 10;

// The shortcuts, in one table: the actions use them and the help overlay lists them.
const std::vector<std::pair<QString, QString>>& shortcutTable() {
  static const std::vector<std::pair<QString, QString>> table = {
      {"1 - 9", "show one image: noisy, denoised, reference, heatmap"},
      {"S", "side by side"},
      {"W", "wipe between A and B (drag the line)"},
      {"Space", "flip between A and B"},
      {"[  ]", "previous / next AOV of the noisy input"},
      {"E  Shift+E", "exposure up / down half a stop"},
      {"R", "reset exposure and offset"},
      {"F", "fit"},
      {"Ctrl+0", "1:1 (one image pixel per screen pixel)"},
      {"+  -  wheel", "zoom (the wheel zooms about the cursor)"},
      {"drag", "pan"},
      {"Shift+drag, right-drag", "region of interest (metrics, ROI denoise)"},
      {"Backspace", "clear the region of interest"},
      {"H", "heatmap: own pane / overlay / off"},
      {"Ctrl+D", "denoise with the selected model"},
      {"Esc", "cancel the denoise, close this help"},
      {"Ctrl+O  Ctrl+Shift+O", "open render / open reference"},
      {"F5", "reload"},
      {"Ctrl+E", "export the denoised EXR"},
      {"Ctrl+Shift+S", "export the comparison as displayed (PNG)"},
      {"?  F1", "this help"},
  };
  return table;
}

QString errorText(const std::exception& e) { return QString::fromStdString(e.what()); }
}  // namespace

struct MainWindow::Rendered {
  std::vector<Pane> panes;
  QSize size;
};

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent) {
  setObjectName("mainWindow");
  setWindowTitle("Residue");
  resize(1500, 900);
  session_ = new Session(this);
  display_ = DisplayTransform::load_default();
  canvas_ = new ImageCanvas(this);
  canvas_->setObjectName("canvas");
  setCentralWidget(canvas_);
  help_ = new HelpOverlay(shortcutTable(), canvas_);
  render_ = std::make_unique<LatestTask<Rendered>>(this, [this](Rendered&& r) { showRendered(std::move(r)); });

  buildDocks();
  buildToolBar();
  buildActions();

  size_label_ = new QLabel(this);
  zoom_label_ = new QLabel(this);
  cursor_label_ = new QLabel(this);
  cursor_label_->setObjectName("cursorLabel");
  cursor_label_->setMinimumWidth(320);
  statusBar()->addPermanentWidget(cursor_label_);
  statusBar()->addPermanentWidget(size_label_);
  statusBar()->addPermanentWidget(zoom_label_);
  statusBar()->showMessage(tr("Colour: %1").arg(QString::fromStdString(display_->source())), 8000);
  if (!display_->note().empty()) statusBar()->showMessage(QString::fromStdString(display_->note()), 15000);

  connect(session_, &Session::loadStarted, this, [this](const QString& what) {
    statusBar()->showMessage(tr("Loading %1...").arg(what));
  });
  connect(session_, &Session::loaded, this, &MainWindow::onLoaded);
  watcher_ = new QFileSystemWatcher(this);
  reload_timer_ = new QTimer(this);
  reload_timer_->setSingleShot(true);
  reload_timer_->setInterval(300);
  const auto changed = [this] {
    if (auto_reload_->isChecked()) reload_timer_->start();
  };
  connect(watcher_, &QFileSystemWatcher::fileChanged, this, changed);
  connect(watcher_, &QFileSystemWatcher::directoryChanged, this, changed);
  connect(reload_timer_, &QTimer::timeout, this, [this] {
    for (const auto& p : session_->inputs())
      if (!std::filesystem::exists(p)) return watchInputs();  // replaced by a rename: not there yet
    auto_reloading_ = true;
    session_->reload();
  });
  connect(session_, &Session::loadFailed, this, &MainWindow::onLoadFailed);
  connect(session_, &Session::referenceChanged, this, [this] {
    statusBar()->showMessage(tr("Reference loaded"), 5000);
    refreshPanes();
    refreshAnalysis();
  });
  connect(session_, &Session::denoisedChanged, this, [this] {
    refreshPanes();
    if (!denoise_->running()) refreshAnalysis();
  });
  connect(session_, &Session::denoisedTileChanged, this, &MainWindow::patchDenoisedTile);
  connect(canvas_, &ImageCanvas::hovered, this, [this](std::optional<QPoint> p) {
    hover_ = p;
    const auto map = heatmap_->map();
    inspector_->inspect(*session_, p, map.get(), heatmap_->title());
    updateStatus();
  });
  connect(canvas_, &ImageCanvas::viewChanged, this, &MainWindow::updateStatus);
  connect(canvas_, &ImageCanvas::roiChanged, this, [this](std::optional<Rect> roi) { setRoi(roi); });
  connect(canvas_, &ImageCanvas::filesDropped, this, [this](const QStringList& files) { openFiles(files); });
  connect(metrics_, &MetricsPanel::optionsChanged, this, &MainWindow::refreshAnalysis);
  connect(heatmap_, &HeatmapPanel::settingsChanged, this, &MainWindow::refreshAnalysis);
  connect(heatmap_, &HeatmapPanel::displayChanged, this, [this] {
    const bool want_pane = heatmap_->display() == HeatmapPanel::Display::Pane && session_->reference();
    if (want_pane != (paneIndex(Source::Heatmap) >= 0)) refreshPanes();
    else applyHeatmap();
  });
  connect(heatmap_, &HeatmapPanel::ready, this, &MainWindow::applyHeatmap);
  connect(denoise_, &DenoisePanel::started, this, [this](const QString& what) {
    run_tiles_.clear();
    statusBar()->showMessage(tr("Denoising with %1").arg(what));
  });
  connect(denoise_, &DenoisePanel::finished, this, [this](bool ok, const QString& message) {
    statusBar()->showMessage(ok ? tr("Denoised: %1").arg(session_->denoisedDescription()) : message, 10000);
    updateTitle();
  });
  rebuildRecentMenu();
  updateStatus();
}

MainWindow::~MainWindow() { render_.reset(); }  // first: its jobs post to this window

void MainWindow::showRendered(Rendered&& r) {
  canvas_->setPanes(std::move(r.panes), r.size);
  // Tiles that landed while these panes were being drawn are in the session: show them too.
  if (const int d = paneIndex(Source::Denoised); d >= 0 && session_->denoised()) {
    canvas_->setPaneValues(d, std::shared_ptr<const Image>(std::shared_ptr<const Image>(), session_->denoised()));
    if (denoise_->running())
      for (const Rect& t : run_tiles_) drawDenoisedTile(t);
  }
  applyHeatmap();
  updateStatus();
  emit panesRendered();
}

// ---------------------------------------------------------------------------------------------------------------
// Construction

void MainWindow::buildDocks() {
  const auto dock = [this](const QString& title, const QString& name, QWidget* w, Qt::DockWidgetArea area) {
    auto* d = new QDockWidget(title, this);
    d->setObjectName(name);
    d->setWidget(w);
    addDockWidget(area, d);
    return d;
  };
  denoise_ = new DenoisePanel(session_, this);
  metrics_ = new MetricsPanel(this);
  heatmap_ = new HeatmapPanel(this);
  inspector_ = new PixelInspector(this);
  dock(tr("Denoise"), "denoiseDock", denoise_, Qt::RightDockWidgetArea);
  dock(tr("Metrics"), "metricsDock", metrics_, Qt::RightDockWidgetArea);
  dock(tr("Heatmap"), "heatmapDock", heatmap_, Qt::RightDockWidgetArea);
  auto* pixel = dock(tr("Pixel"), "inspectorDock", inspector_, Qt::LeftDockWidgetArea);
  resizeDocks({pixel}, {230}, Qt::Horizontal);
}

void MainWindow::buildToolBar() {
  auto* bar = addToolBar(tr("View"));
  bar->setObjectName("viewToolBar");
  layout_box_ = new QComboBox(this);
  layout_box_->setObjectName("layoutBox");
  layout_box_->addItems({tr("Side by side"), tr("Single"), tr("Wipe")});
  bar->addWidget(new QLabel(tr(" Layout "), this));
  bar->addWidget(layout_box_);
  connect(layout_box_, &QComboBox::currentIndexChanged, this, [this](int i) {
    canvas_->setLayout(i == 0 ? ImageCanvas::Layout::SideBySide : i == 1 ? ImageCanvas::Layout::Single
                                                                         : ImageCanvas::Layout::Wipe);
  });
  aov_box_ = new QComboBox(this);
  aov_box_->setObjectName("aovBox");
  for (AovRole v : kViewableAovs) aov_box_->addItem(display_name(v), static_cast<int>(v));
  bar->addWidget(new QLabel(tr("  AOV "), this));
  bar->addWidget(aov_box_);
  connect(aov_box_, &QComboBox::currentIndexChanged, this,
          [this] { setAov(static_cast<AovRole>(aov_box_->currentData().toInt())); });

  exposure_box_ = new QDoubleSpinBox(this);
  exposure_box_->setObjectName("exposureBox");
  exposure_box_->setRange(-20, 20);
  exposure_box_->setSingleStep(0.5);
  exposure_box_->setDecimals(1);
  exposure_box_->setToolTip(tr("Exposure in stops (E / Shift+E)"));
  bar->addWidget(new QLabel(tr("  Exposure "), this));
  bar->addWidget(exposure_box_);
  offset_box_ = new QDoubleSpinBox(this);
  offset_box_->setObjectName("offsetBox");
  offset_box_->setRange(-10, 10);
  offset_box_->setSingleStep(0.01);
  offset_box_->setDecimals(3);
  offset_box_->setToolTip(tr("Offset added after the exposure"));
  bar->addWidget(new QLabel(tr(" Offset "), this));
  bar->addWidget(offset_box_);
  connect(exposure_box_, &QDoubleSpinBox::valueChanged, this, &MainWindow::refreshPanes);
  connect(offset_box_, &QDoubleSpinBox::valueChanged, this, &MainWindow::refreshPanes);

  display_box_ = new QComboBox(this);
  display_box_->setObjectName("displayBox");
  view_box_ = new QComboBox(this);
  view_box_->setObjectName("viewBox");
  for (const auto& d : display_->displays()) display_box_->addItem(QString::fromStdString(d));
  display_box_->setCurrentText(QString::fromStdString(display_->default_display()));
  const auto fill_views = [this] {
    const std::string d = display_box_->currentText().toStdString();
    QSignalBlocker block(view_box_);
    view_box_->clear();
    for (const auto& v : display_->views(d)) view_box_->addItem(QString::fromStdString(v));
    view_box_->setCurrentText(QString::fromStdString(display_->default_view(d)));
  };
  fill_views();
  connect(display_box_, &QComboBox::currentIndexChanged, this, [this, fill_views] {
    fill_views();
    refreshPanes();
  });
  connect(view_box_, &QComboBox::currentIndexChanged, this, &MainWindow::refreshPanes);
  bar->addWidget(new QLabel(tr("  Display "), this));
  bar->addWidget(display_box_);
  bar->addWidget(view_box_);
  display_box_->setToolTip(tr("OpenColorIO display and view (%1)").arg(QString::fromStdString(display_->source())));
  view_box_->setToolTip(display_box_->toolTip());
}

void MainWindow::buildActions() {
  const auto action = [this](QMenu* menu, const QString& text, const QKeySequence& key, auto slot) {
    auto* a = new QAction(text, this);
    if (!key.isEmpty()) a->setShortcut(key);
    a->setShortcutContext(Qt::WindowShortcut);
    connect(a, &QAction::triggered, this, slot);
    menu->addAction(a);
    addAction(a);
    return a;
  };
  auto* file = menuBar()->addMenu(tr("&File"));
  action(file, tr("&Open..."), QKeySequence::Open, [this] {
    const QStringList files = QFileDialog::getOpenFileNames(this, tr("Open a render (AOV stack)"), QString(),
                                                            tr("OpenEXR (*.exr);;All files (*)"));
    if (!files.isEmpty()) openFiles(files);
  });
  action(file, tr("Open &Reference..."), QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_O), [this] {
    const QString f = QFileDialog::getOpenFileName(this, tr("Open a reference image"), QString(),
                                                   tr("OpenEXR (*.exr);;All files (*)"));
    if (!f.isEmpty()) openReferenceFile(f);
  });
  recent_menu_ = file->addMenu(tr("Open Re&cent"));
  action(file, tr("Re&load"), QKeySequence(Qt::Key_F5), [this] { session_->reload(); });
  auto_reload_ = action(file, tr("Reload When the Files Change"), QKeySequence(), [this] { watchInputs(); });
  auto_reload_->setCheckable(true);
  auto_reload_->setChecked(true);
  live_denoise_ = action(file, tr("Denoise Streamed Images When They Pause"), QKeySequence(), [] {});
  live_denoise_->setCheckable(true);
  live_denoise_->setChecked(true);
  file->addSeparator();
  auto* exp = file->addMenu(tr("&Export"));
  action(exp, tr("Denoised image (EXR)..."), QKeySequence(Qt::CTRL | Qt::Key_E), [this] {
    if (!session_->denoised()) return void(QMessageBox::information(this, tr("Export"), tr("Denoise first.")));
    // Pixel type and compression, as residue-cli offers them.
    QDialog dlg(this);
    dlg.setWindowTitle(tr("EXR options"));
    auto* form = new QFormLayout(&dlg);
    auto* type = new QComboBox(&dlg);
    type->addItems({"half", "float"});
    auto* comp = new QComboBox(&dlg);
    comp->addItems({"zip", "piz", "zips", "rle", "pxr24", "b44", "b44a", "dwaa", "dwab", "none"});
    form->addRow(tr("Pixel type"), type);
    form->addRow(tr("Compression"), comp);
    auto* buttons = new QDialogButtonBox(QDialogButtonBox::Ok | QDialogButtonBox::Cancel, &dlg);
    form->addRow(buttons);
    connect(buttons, &QDialogButtonBox::accepted, &dlg, &QDialog::accept);
    connect(buttons, &QDialogButtonBox::rejected, &dlg, &QDialog::reject);
    if (dlg.exec() != QDialog::Accepted) return;
    const QString path = askSavePath(tr("Export the denoised image"), tr("OpenEXR (*.exr)"), "exr");
    if (!path.isEmpty())
      runExport(tr("denoised EXR"), exportDenoisedExr(path, true, type->currentIndex() == 0, comp->currentText()));
  });
  action(exp, tr("Heatmap (PNG)..."), QKeySequence(), [this] {
    const QString path = askSavePath(tr("Export the heatmap"), tr("PNG (*.png)"), "png");
    if (!path.isEmpty()) runExport(tr("heatmap PNG"), exportHeatmap(path, true));
  });
  action(exp, tr("Heatmap values (EXR)..."), QKeySequence(), [this] {
    const QString path = askSavePath(tr("Export the heatmap values"), tr("OpenEXR (*.exr)"), "exr");
    if (!path.isEmpty()) runExport(tr("heatmap EXR"), exportHeatmap(path, true));
  });
  action(exp, tr("Comparison as displayed (PNG)..."), QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_S), [this] {
    const QString path = askSavePath(tr("Export the comparison"), tr("PNG (*.png)"), "png");
    if (!path.isEmpty()) runExport(tr("comparison PNG"), exportComparison(path, true));
  });
  action(exp, tr("Metrics (JSON or CSV)..."), QKeySequence(), [this] {
    const QString path = askSavePath(tr("Export the metrics"), tr("JSON (*.json);;CSV (*.csv)"), "json");
    if (!path.isEmpty()) runExport(tr("metrics"), exportMetrics(path, true));
  });
  file->addSeparator();
  action(file, tr("&Quit"), QKeySequence::Quit, [this] { close(); });

  auto* view = menuBar()->addMenu(tr("&View"));
  action(view, tr("Side by side"), QKeySequence(Qt::Key_S), [this] { layout_box_->setCurrentIndex(0); });
  action(view, tr("Wipe A | B"), QKeySequence(Qt::Key_W), [this] { layout_box_->setCurrentIndex(2); });
  action(view, tr("Flip A / B"), QKeySequence(Qt::Key_Space), [this] {
    layout_box_->setCurrentIndex(1);
    canvas_->flipAB();
  });
  auto* pick = view->addMenu(tr("Wipe pair"));
  for (int a = 0; a < 3; ++a) {
    for (int b = a + 1; b < 4; ++b) {
      const Source sa = static_cast<Source>(a), sb = static_cast<Source>(b);
      action(pick, QString("%1 | %2").arg(QString::fromLatin1(to_string(sa)), QString::fromLatin1(to_string(sb))),
             QKeySequence(), [this, sa, sb] {
               canvas_->setWipePair(paneIndex(sa), paneIndex(sb));
               layout_box_->setCurrentIndex(2);
             });
    }
  }
  view->addSeparator();
  for (int i = 1; i <= 9; ++i) {
    action(view, tr("Image %1").arg(i), QKeySequence(Qt::Key_0 + i), [this, i] {
      if (i - 1 < static_cast<int>(pane_sources_.size())) showPane(pane_sources_[static_cast<size_t>(i - 1)]);
    });
  }
  view->addSeparator();
  action(view, tr("Fit"), QKeySequence(Qt::Key_F), [this] { canvas_->fit(); });
  action(view, tr("1:1"), QKeySequence(Qt::CTRL | Qt::Key_0), [this] { canvas_->oneToOne(); });
  auto* zin = action(view, tr("Zoom in"), QKeySequence(Qt::Key_Plus), [this] { canvas_->zoomBy(2.0); });
  zin->setShortcuts({QKeySequence(Qt::Key_Plus), QKeySequence(Qt::Key_Equal), QKeySequence::ZoomIn});
  auto* zout = action(view, tr("Zoom out"), QKeySequence(Qt::Key_Minus), [this] { canvas_->zoomBy(0.5); });
  zout->setShortcuts({QKeySequence(Qt::Key_Minus), QKeySequence::ZoomOut});
  view->addSeparator();
  action(view, tr("Exposure +1/2 stop"), QKeySequence(Qt::Key_E), [this] { setExposure(exposure() + 0.5); });
  action(view, tr("Exposure -1/2 stop"), QKeySequence(Qt::SHIFT | Qt::Key_E), [this] { setExposure(exposure() - 0.5); });
  action(view, tr("Reset exposure and offset"), QKeySequence(Qt::Key_R), [this] {
    setExposure(0);
    offset_box_->setValue(0);
  });
  action(view, tr("Next AOV"), QKeySequence(Qt::Key_BracketRight), [this] { cycleAov(+1); });
  action(view, tr("Previous AOV"), QKeySequence(Qt::Key_BracketLeft), [this] { cycleAov(-1); });
  action(view, tr("Heatmap: pane / overlay / off"), QKeySequence(Qt::Key_H), [this] {
    const auto d = heatmap_->display();
    heatmap_->setDisplay(d == HeatmapPanel::Display::Pane      ? HeatmapPanel::Display::Overlay
                         : d == HeatmapPanel::Display::Overlay ? HeatmapPanel::Display::Off
                                                               : HeatmapPanel::Display::Pane);
  });
  action(view, tr("Clear region of interest"), QKeySequence(Qt::Key_Backspace), [this] { setRoi(std::nullopt); });

  auto* den = menuBar()->addMenu(tr("&Denoise"));
  action(den, tr("&Denoise"), QKeySequence(Qt::CTRL | Qt::Key_D), [this] { denoise_->start(); });
  action(den, tr("&Cancel"), QKeySequence(), [this] { denoise_->cancel(); });

  auto* help = menuBar()->addMenu(tr("&Help"));
  auto* keys = action(help, tr("Keyboard shortcuts"), QKeySequence(Qt::Key_Question), [this] { help_->toggle(); });
  // "?" arrives as Shift+? on most layouts and platforms; F1 is the usual help key.
  keys->setShortcuts({QKeySequence(Qt::Key_Question), QKeySequence(Qt::SHIFT | Qt::Key_Question), QKeySequence(Qt::Key_F1)});
  action(help, tr("About Residue"), QKeySequence(), [this] {
    QMessageBox::about(this, tr("About Residue"),
                       tr("<b>Residue %1</b><p>Monte Carlo render denoising with a direct residual network "
                          "(Wong &amp; Wong 2019), and the tools to judge it.</p><p>Colour: %2</p>")
                           .arg(RESIDUE_VERSION, QString::fromStdString(display_->source()).toHtmlEscaped()));
  });
}

// ---------------------------------------------------------------------------------------------------------------
// Opening

void MainWindow::openFiles(const QStringList& files, const LoadOptions& options) {
  if (files.isEmpty()) return;
  std::vector<std::filesystem::path> inputs;
  for (const auto& f : files) inputs.emplace_back(f.toStdString());
  last_error_.clear();
  mapping_retry_ = false;
  session_->open(inputs, options);
  addRecent(files);
}

void MainWindow::openReferenceFile(const QString& file) {
  if (!session_->hasStack()) {
    last_error_ = tr("Open a render before its reference.");
    if (interactive_) QMessageBox::information(this, tr("Open Reference"), last_error_);
    return;
  }
  session_->openReference(file.toStdString());
}

void MainWindow::onLoaded() {
  const auto stack = session_->stack();
  last_error_.clear();
  // Fall back to colour when the new render lacks the AOV being shown.
  if (!session_->hasAov(aov_)) setAov(AovRole::Color);
  for (int i = 0; i < aov_box_->count(); ++i) {
    const bool has = session_->hasAov(static_cast<AovRole>(aov_box_->itemData(i).toInt()));
    auto* model = qobject_cast<QStandardItemModel*>(aov_box_->model());
    if (model) model->item(i)->setEnabled(has);
  }
  QStringList notes;
  for (const auto& n : stack->notes) notes << QString::fromStdString(n);
  statusBar()->showMessage(tr("Loaded %1 (%2)%3")
                               .arg(session_->title(), QString::fromStdString(stack->convention),
                                    notes.isEmpty() ? QString() : " - " + notes.join("; ")),
                           10000);
  updateTitle();
  refreshPanes();
  refreshAnalysis();
  auto_reloading_ = false;
  watchInputs();
}

void MainWindow::watchInputs() {
  if (const QStringList watched = watcher_->files() + watcher_->directories(); !watched.isEmpty())
    watcher_->removePaths(watched);
  if (!auto_reload_->isChecked() || !session_->liveName().isEmpty()) return;
  // A renderer that replaces the file by a rename drops it from the watch: it is added again after each load.
  for (const auto& p : session_->inputs())
    if (std::filesystem::exists(p)) watcher_->addPath(QString::fromStdString(p.string()));
  if (const auto& ref = session_->loadOptions().reference; ref && std::filesystem::exists(*ref))
    watcher_->addPath(QString::fromStdString(ref->string()));
}

void MainWindow::onLoadFailed(const QString& message, int kind, const QStringList& inputs) {
  last_error_ = message;
  statusBar()->showMessage(tr("Could not load: %1").arg(message), 15000);
  if (auto_reloading_) {  // a file caught half-written: the next change reloads it again
    auto_reloading_ = false;
    watchInputs();
    return;
  }
  // Channels that no convention recognises: let the user assign them (once per channel layout).
  const bool mapping_problem = kind == static_cast<int>(ErrorKind::Mapping) ||
                               (kind == static_cast<int>(ErrorKind::Input) && message.contains("channel"));
  if (mapping_problem && inputs.size() == 1 && QFileInfo(inputs.front()).isFile()) {
    MappingDialog probe(inputs.front().toStdString(), message, this);
    if (!mapping_retry_) {
      if (const auto remembered = remembered_mapping(probe.channels())) {
        mapping_retry_ = true;
        LoadOptions o;
        try {
          for (const auto& f : *remembered) o.mapping.add_flag(f.toStdString());
          session_->open({inputs.front().toStdString()}, o);
          return;
        } catch (const std::exception&) {
          // a remembered mapping that no longer parses: ask again
        }
      }
    }
    if (!interactive_) return;
    if (probe.exec() == QDialog::Accepted) {
      try {
        LoadOptions o;
        o.mapping = probe.mapping();
        remember_mapping(probe.channels(), probe.flags());
        mapping_retry_ = true;
        session_->open({inputs.front().toStdString()}, o);
      } catch (const std::exception& e) {
        QMessageBox::warning(this, tr("Channel mapping"), errorText(e));
      }
    }
    return;
  }
  if (interactive_) QMessageBox::warning(this, tr("Could not load"), message);
}

void MainWindow::addRecent(const QStringList& files) {
  QSettings s;
  QStringList recent = s.value("recentFiles").toStringList();
  const QString entry = files.join('\n');
  recent.removeAll(entry);
  recent.prepend(entry);
  while (recent.size() > kMaxRecent) recent.removeLast();
  s.setValue("recentFiles", recent);
  rebuildRecentMenu();
}

void MainWindow::rebuildRecentMenu() {
  recent_menu_->clear();
  const QStringList recent = QSettings().value("recentFiles").toStringList();
  for (const QString& entry : recent) {
    const QStringList files = entry.split('\n');
    QStringList names;
    for (const auto& f : files) names << QFileInfo(f).fileName();
    auto* a = recent_menu_->addAction(names.join(", "));
    a->setToolTip(entry);
    connect(a, &QAction::triggered, this, [this, files] { openFiles(files); });
  }
  recent_menu_->setEnabled(!recent.isEmpty());
}

// ---------------------------------------------------------------------------------------------------------------
// View

DisplaySettings MainWindow::displaySettings() const {
  DisplaySettings s;
  s.exposure = exposure_box_->value();
  s.offset = offset_box_->value();
  s.display = display_box_->currentText().toStdString();
  s.view = view_box_->currentText().toStdString();
  return s;
}

void MainWindow::setExposure(double stops) { exposure_box_->setValue(stops); }
double MainWindow::exposure() const { return exposure_box_->value(); }

void MainWindow::setAov(AovRole aov) {
  if (aov_ == aov && aov_box_->currentData().toInt() == static_cast<int>(aov)) return;
  aov_ = aov;
  aov_box_->setCurrentIndex(aov_box_->findData(static_cast<int>(aov)));
  refreshPanes();
}

void MainWindow::cycleAov(int step) {
  if (!session_->hasStack()) return;
  const int n = static_cast<int>(std::size(kViewableAovs));
  int i = static_cast<int>(std::find(std::begin(kViewableAovs), std::end(kViewableAovs), aov_) - std::begin(kViewableAovs));
  for (int k = 0; k < n; ++k) {
    i = (i + step + n) % n;
    if (session_->hasAov(kViewableAovs[i])) break;
  }
  setAov(kViewableAovs[i]);
  statusBar()->showMessage(tr("AOV: %1").arg(display_name(aov_)), 3000);
}

void MainWindow::showPane(Source s) {
  const int i = paneIndex(s);
  if (i < 0) return;
  canvas_->setCurrent(i);
  layout_box_->setCurrentIndex(1);
}

void MainWindow::setLayout(ImageCanvas::Layout layout) {
  layout_box_->setCurrentIndex(layout == ImageCanvas::Layout::SideBySide ? 0 : layout == ImageCanvas::Layout::Single ? 1 : 2);
}

int MainWindow::paneIndex(Source s) const {
  for (size_t i = 0; i < pane_sources_.size(); ++i)
    if (pane_sources_[i] == s) return static_cast<int>(i);
  return -1;
}

void MainWindow::setRoi(std::optional<Rect> roi) {
  canvas_->setRoi(roi);
  denoise_->setRoi(canvas_->roi());
  refreshAnalysis();
}

std::shared_ptr<const Image> MainWindow::shared(Source s) const {
  if (s == Source::Denoised) return session_->denoisedShared();
  const auto stack = session_->stack();
  const Image* img = session_->image(s, AovRole::Color);
  // Aliasing: the image lives as long as the stack it belongs to.
  return img ? std::shared_ptr<const Image>(stack, img) : nullptr;
}

bool MainWindow::rendering() const { return render_->busy(); }

bool MainWindow::busy() const {
  return session_->loading() || rendering() || metrics_->busy() || heatmap_->busy() || denoise_->running() ||
         exports_running_ > 0;
}

void MainWindow::refreshPanes() {
  if (!session_ || !canvas_ || !render_) return;
  if (!session_->hasStack()) {
    render_->supersede();
    pane_sources_.clear();
    canvas_->setPanes({}, {});
    return;
  }
  const auto stack = session_->stack();
  pane_sources_ = {Source::Noisy, Source::Denoised};
  if (session_->reference()) {
    pane_sources_.push_back(Source::Reference);
    if (heatmap_->display() == HeatmapPanel::Display::Pane) pane_sources_.push_back(Source::Heatmap);
  }
  PaneInputs in;
  in.sources = pane_sources_;
  in.stack = stack;
  in.aov = aov_;
  in.noisy = session_->image(Source::Noisy, aov_);
  // During a run from the noisy colour the unfinished tiles *are* the noisy colour: draw from the stack (which
  // never changes) rather than holding the image the tiles are written into (that would copy it per tile).
  in.denoised = denoise_->runningFromNoisy() ? shared(Source::Noisy) : session_->denoisedShared();
  in.reference = shared(Source::Reference);
  in.heat_image = heatmap_->image();
  in.heat_map = heatmap_->map();
  in.heat_title = heatmap_->title();
  in.model = session_->denoisedDescription();
  in.display = display_;
  in.settings = displaySettings();
  const QSize size(static_cast<int>(stack->width()), static_cast<int>(stack->height()));
  render_->start([this, in, size](const LatestTask<Rendered>::Token& token) {
    // A large render is first shown from every step-th pixel (what a fitted view needs), then in full.
    if (const int step = preview_step(size.width(), size.height()); step > 1) {
      auto preview = std::make_shared<Rendered>(Rendered{render_panes(in, step), size});
      QMetaObject::invokeMethod(this, [this, preview, generation = token.generation()] {
        if (render_->pending(generation)) canvas_->setPanes(std::move(preview->panes), preview->size);
        applyHeatmap();
        emit panesRendered();
      }, Qt::QueuedConnection);
    }
    return Rendered{render_panes(in, 1), size};
  });
}

void MainWindow::patchDenoisedTile(const Rect& rect) {
  if (denoise_->running()) run_tiles_.push_back(rect);
  drawDenoisedTile(rect);
}

void MainWindow::drawDenoisedTile(const Rect& rect) {
  const int i = paneIndex(Source::Denoised);
  const Image* d = session_->denoised();
  if (i < 0 || !d) return;
  try {
    canvas_->patchPane(i, QPoint(static_cast<int>(rect.x), static_cast<int>(rect.y)),
                       display_->render(*d, 0, 3, rect, displaySettings(), Encoding::SceneLinear));
    canvas_->setPaneValues(i, std::shared_ptr<const Image>(std::shared_ptr<const Image>(), d));
  } catch (const std::exception&) {
    // a display/view that cannot be built is reported by the full render
  }
}

void MainWindow::refreshAnalysis() {
  if (!session_->hasStack()) return;
  const auto stack = session_->stack();
  MetricsPanel::Inputs in;
  in.noisy = shared(Source::Noisy);
  in.denoised = denoise_->running() ? nullptr : session_->denoisedShared();
  in.reference = shared(Source::Reference);
  in.noisy_file = QString::fromStdString(stack->color.source.file);
  in.denoised_file = session_->denoisedDescription();
  if (stack->reference) in.reference_file = QString::fromStdString(stack->reference->source.file);
  in.roi = canvas_->roi();
  in.noisy_nan = stack->color.non_finite.nan;
  in.noisy_inf = stack->color.non_finite.inf;
  if (stack->reference) {
    in.reference_nan = stack->reference->non_finite.nan;
    in.reference_inf = stack->reference->non_finite.inf;
  }
  metrics_->compute(in);
  // The map is computed even when hidden: the inspector and the export read it.
  heatmap_->compute(in.noisy, in.denoised, in.reference, metrics_->options());
}

void MainWindow::applyHeatmap() {
  canvas_->clearOverlays();
  const auto d = heatmap_->display();
  if (d == HeatmapPanel::Display::Pane) {
    const int i = paneIndex(Source::Heatmap);
    if (i >= 0) {
      canvas_->setPaneDisplay(i, heatmap_->image());
      canvas_->setPaneValues(i, heatmap_->map());
    }
  } else if (d == HeatmapPanel::Display::Overlay) {
    const int i = paneIndex(heatmap_->of() == HeatmapPanel::Of::Noisy ? Source::Noisy : Source::Denoised);
    if (i >= 0 && !heatmap_->image().isNull()) canvas_->setOverlay(i, heatmap_->image());
  }
}

void MainWindow::updateStatus() {
  if (!session_->hasStack()) {
    size_label_->setText(tr("no image"));
    zoom_label_->clear();
    cursor_label_->clear();
    return;
  }
  const auto stack = session_->stack();
  size_label_->setText(QString("%1 x %2").arg(stack->width()).arg(stack->height()));
  zoom_label_->setText(QString("%1%").arg(canvas_->zoom() * 100.0, 0, 'f', canvas_->zoom() < 0.1 ? 1 : 0));
  if (hover_) {
    QString text = QString("x %1  y %2").arg(hover_->x()).arg(hover_->y());
    // The values of the pane under the cursor (the noisy colour when it has none, e.g. a pane still rendering).
    const Pane* pane = nullptr;
    if (const auto i = canvas_->hoveredPane(); i && *i < static_cast<int>(canvas_->panes().size()))
      pane = &canvas_->panes()[static_cast<size_t>(*i)];
    const Image* values = pane && pane->values ? pane->values.get() : &stack->color.image;
    const int first = pane && pane->values ? pane->first_channel : 0;
    const int count = pane && pane->values ? std::min(pane->channel_count, values->channels() - first) : 3;
    text += "  " + (pane && pane->values ? pane->label : tr("Noisy"));
    if (hover_->x() < values->width() && hover_->y() < values->height())
      for (int c = 0; c < count; ++c)
        text += QString(" %1").arg(static_cast<double>(values->at(hover_->x(), hover_->y(), first + c)), 0, 'g', 4);
    cursor_label_->setText(text);
  } else {
    cursor_label_->clear();
  }
}

QString MainWindow::listenForRenderers(quint16 port) {
  if (!tev_) {
    tev_ = new TevServer(this);
    live_timer_ = new QTimer(this);
    live_timer_->setSingleShot(true);
    live_timer_->setInterval(150);  // a renderer sends many tiles a second; show them a few times a second
    live_quiet_ = new QTimer(this);
    live_quiet_->setSingleShot(true);
    live_quiet_->setInterval(1000);
    connect(tev_, &TevServer::liveImageChanged, this, [this](const QString& name) {
      live_pending_ = name;
      if (!live_timer_->isActive()) live_timer_->start();
      live_quiet_->start();  // restarted by every update: fires once the stream pauses
    });
    connect(live_quiet_, &QTimer::timeout, this, [this] {
      if (!live_denoise_->isChecked() || session_->liveName().isEmpty() || denoise_->running()) return;
      if (live_timer_->isActive()) return live_quiet_->start();  // the last tiles are not shown yet
      denoise_->start();
    });
    connect(live_timer_, &QTimer::timeout, this, [this] {
      const ipc::LiveImage* live = tev_->images().find(live_pending_.toStdString());
      if (!live) return;
      try {
        session_->adoptLive(std::make_shared<const AovStack>(ipc::live_aov_stack(live_pending_.toStdString(), *live)),
                            live_pending_);
      } catch (const std::exception& e) {
        statusBar()->showMessage(errorText(e), 10000);
      }
    });
    connect(tev_, &TevServer::openRequested, this, [this](const QString& path, const QString& channels) {
      if (!channels.isEmpty())
        statusBar()->showMessage(tr("Opening %1 (channel selector \"%2\" ignored: AOVs are recognised by name)")
                                     .arg(path, channels), 10000);
      openFiles({path});
    });
    connect(tev_, &TevServer::reloadRequested, this, [this] { session_->reload(); });
    connect(tev_, &TevServer::protocolError, this, [this](const QString& message) {
      statusBar()->showMessage(message, 15000);
    });
  }
  if (tev_->listening()) return {};
  return tev_->listen(port) ? QString() : tev_->errorString();
}

void MainWindow::updateTitle() {
  QString t = session_->hasStack() ? session_->title() + " - Residue" : QStringLiteral("Residue");
  setWindowTitle(t);
}

void MainWindow::keyPressEvent(QKeyEvent* e) {
  if (e->key() == Qt::Key_Escape) {
    if (help_->isVisible()) help_->hide();
    else denoise_->cancel();
    return;
  }
  QMainWindow::keyPressEvent(e);
}

void MainWindow::closeEvent(QCloseEvent* e) {
  denoise_->cancel();
  QMainWindow::closeEvent(e);
}

// ---------------------------------------------------------------------------------------------------------------
// Export

QString MainWindow::askSavePath(const QString& title, const QString& filter, const QString& suffix) {
  QFileDialog dlg(this, title, QString(), filter);
  dlg.setAcceptMode(QFileDialog::AcceptSave);
  dlg.setDefaultSuffix(suffix);
  // The dialog asks before replacing an existing file (ConfirmOverwrite is on by default).
  if (dlg.exec() != QDialog::Accepted || dlg.selectedFiles().isEmpty()) return {};
  return dlg.selectedFiles().front();
}

void MainWindow::runExport(const QString& what, QFuture<QString> future) {
  ++exports_running_;
  statusBar()->showMessage(tr("Writing %1...").arg(what));
  auto* w = new QFutureWatcher<QString>(this);
  connect(w, &QFutureWatcherBase::finished, this, [this, w, what] {
    --exports_running_;
    const QString error = w->result();
    if (error.isEmpty()) statusBar()->showMessage(tr("Wrote the %1").arg(what), 8000);
    else if (interactive_) QMessageBox::warning(this, tr("Export failed"), error);
    else statusBar()->showMessage(error, 15000);
    w->deleteLater();
  });
  w->setFuture(future);
}

QFuture<QString> MainWindow::exportDenoisedExr(const QString& path, bool overwrite, bool half,
                                               const QString& compression) {
  const auto denoised = session_->denoisedShared();
  const auto stack = session_->stack();
  const QString description = session_->denoisedDescription();
  const float strength = session_->strength();
  return QtConcurrent::run([=]() -> QString {
    if (!denoised || !stack) return tr("Nothing to export: no denoised image.");
    try {
      io::ExrWriteOptions o;
      o.pixel_type = half ? io::PixelType::Half : io::PixelType::Float;
      o.compression = compression.toStdString();
      o.metadata = stack->metadata;
      o.data_window = stack->data_window;
      o.display_width = stack->display_width;
      o.display_height = stack->display_height;
      o.residue_attributes.attribute("residue:model", description.toStdString());
      o.residue_attributes.attribute("residue:source", stack->color.source.file);
      o.residue_attributes.attribute("residue:strength", strength);
      o.residue_attributes.attribute("residue:version", std::string(RESIDUE_VERSION));
      o.residue_attributes.attribute("residue:written_by", std::string("residue viewer"));
      o.overwrite = overwrite;
      io::write_exr(path.toStdString(), *denoised, o);
      return {};
    } catch (const std::exception& e) {
      return errorText(e);
    }
  });
}

QFuture<QString> MainWindow::exportHeatmap(const QString& path, bool overwrite) {
  const auto map = heatmap_->map();
  io::MapPngOptions o;
  o.colormap = heatmap_->colormap();
  o.scale = heatmap_->scale();
  o.overwrite = overwrite;
  return QtConcurrent::run([=]() -> QString {
    if (!map) return tr("Nothing to export: no heatmap (it needs a reference).");
    try {
      if (path.endsWith(".exr", Qt::CaseInsensitive)) io::write_map_exr(path.toStdString(), *map, overwrite);
      else io::write_map_png(path.toStdString(), *map, o);
      return {};
    } catch (const std::exception& e) {
      return errorText(e);
    }
  });
}

QFuture<QString> MainWindow::exportComparison(const QString& path, bool overwrite) {
  // Grabbed on the UI thread (it is what is on screen), encoded and written on a worker.
  const QImage shot = canvas_->grab().toImage();
  return QtConcurrent::run([=]() -> QString {
    try {
      io::write_atomically(path.toStdString(), overwrite, [&](const std::filesystem::path& tmp) {
        if (!shot.save(QString::fromStdString(tmp.string()), "PNG"))
          throw Error(ErrorKind::Output, "could not encode the comparison PNG for " + path.toStdString());
      });
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

}  // namespace residue::ui
