#include "ui/main_window.h"

#include <QAction>
#include <QApplication>
#include <QCloseEvent>
#include <QComboBox>
#include <QDialog>
#include <QDialogButtonBox>
#include <QDir>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QFileSystemWatcher>
#include <QFormLayout>
#include <QGuiApplication>
#include <QKeyEvent>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <QSettings>
#include <QStandardItemModel>
#include <QScreen>
#include <QStatusBar>
#include <QTabWidget>
#include <QTimer>
#include <QToolBar>
#include <QtConcurrent/QtConcurrentRun>
#include <OpenImageIO/imageio.h>
#include <cmath>

#include "core/io/atomic_file.h"
#include "core/io/exr_writer.h"
#include "core/io/map_writer.h"
#include "core/io/metrics_report.h"
#include "core/util/error.h"
#include "ui/comparison_sheet.h"
#include "ui/denoise_panel.h"
#include "ui/export_all.h"
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
      {"1 - 9", "show result 1-9 (rows of the Results tab) as A"},
      {"Ctrl+1 - 9", "show result 1-9 as B, beside A"},
      {"Tab  Shift+Tab", "single layout: next / previous pane"},
      {"A", "all panes, in a grid"},
      {"S", "A and B side by side"},
      {"W", "wipe between A and B (drag the line)"},
      {"Space", "flip between A and B"},
      {"D", "difference: the map of A against B"},
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
      {"Ctrl+Shift+A", "add a result to compare (or drop files on the image)"},
      {"F5", "reload"},
      {"Ctrl+E", "export the denoised EXR"},
      {"Ctrl+Shift+S", "export the comparison sheet (PNG)"},
      {"Ctrl+Shift+E", "export all: results, heatmaps, metrics, sheet"},
      {"F9", "hide / show the side bar"},
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
  // Canvas first: most of the window is image, whatever the screen (1280x720 included).
  if (const QScreen* screen = QGuiApplication::primaryScreen()) {
    const QSize avail = screen->availableSize();
    resize(std::min(1500, avail.width() * 19 / 20), std::min(900, avail.height() * 9 / 10));
  } else {
    resize(1280, 720);
  }
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
    refreshAnalysis();
  });
  connect(session_, &Session::compareChanged, this, [this] {
    refreshPanes();
    refreshAnalysis();
  });
  connect(session_, &Session::resultsChanged, this, [this] {
    refreshAnalysis();
    updateTitle();
  });
  connect(session_, &Session::resultFailed, this, [this](const QString& message) {
    last_error_ = message;
    statusBar()->showMessage(message, 15000);
    if (interactive_) QMessageBox::warning(this, tr("Add result"), message);
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
  connect(canvas_, &ImageCanvas::filesDropped, this, [this](const QStringList& files) {
    // With a render open, images of its size with nothing but colour are results to compare; anything else
    // is a new render.
    QStringList results;
    for (const auto& f : files)
      if (looksLikeResult(f)) results << f;
    if (results.size() == files.size()) addResultFiles(results);
    else openFiles(files);
  });
  connect(metrics_, &MetricsPanel::showAsA, session_, &Session::setA);
  connect(metrics_, &MetricsPanel::showAsB, session_, &Session::setB);
  connect(metrics_, &MetricsPanel::removeRequested, session_, &Session::removeResult);
  connect(metrics_, &MetricsPanel::addRequested, this, [this] {
    const QStringList files = QFileDialog::getOpenFileNames(this, tr("Add results to compare"), QString(),
                                                            tr("Images (*.exr *.hdr *.pfm *.tif *.tiff *.png);;All files (*)"));
    addResultFiles(files);
  });
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
    refreshPanes();  // the pane labels say whether the result is complete
    refreshAnalysis();
  });
  rebuildRecentMenu();
  updateStatus();
}

MainWindow::~MainWindow() { render_.reset(); }  // first: its jobs post to this window

void MainWindow::showRendered(Rendered&& r) {
  canvas_->setPanes(std::move(r.panes), r.size);
  setWipePair(wipe_a_, wipe_b_);
  if (pending_pane_ && paneIndex(*pending_pane_) >= 0) {
    showPane(*pending_pane_);
    pending_pane_.reset();
  }
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
  // One side bar of tabs: the canvas keeps most of the window, and the bar can be closed (View > Side Bar).
  denoise_ = new DenoisePanel(session_, this);
  metrics_ = new MetricsPanel(this);
  heatmap_ = new HeatmapPanel(this);
  inspector_ = new PixelInspector(this);
  tabs_ = new QTabWidget(this);
  tabs_->setObjectName("sideTabs");
  tabs_->addTab(metrics_, tr("Results"));
  tabs_->addTab(denoise_, tr("Denoise"));
  tabs_->addTab(heatmap_, tr("Heatmap"));
  tabs_->addTab(inspector_, tr("Pixel"));
  tabs_->setCurrentWidget(denoise_);
  auto* dock = new QDockWidget(tr("Residue"), this);
  dock->setObjectName("sideDock");
  dock->setWidget(tabs_);
  dock->setFeatures(QDockWidget::DockWidgetClosable | QDockWidget::DockWidgetMovable | QDockWidget::DockWidgetFloatable);
  dock->setTitleBarWidget(new QWidget(dock));  // the tabs are the title
  addDockWidget(Qt::RightDockWidgetArea, dock);
  resizeDocks({dock}, {400}, Qt::Horizontal);
}

void MainWindow::buildToolBar() {
  auto* bar = addToolBar(tr("View"));
  bar->setObjectName("viewToolBar");
  layout_box_ = new QComboBox(this);
  layout_box_->setObjectName("layoutBox");
  layout_box_->addItems({tr("All"), tr("Single"), tr("A | B"), tr("Wipe A | B")});
  layout_box_->setToolTip(tr("All panes in a grid (A), one pane (Tab cycles, Space flips A and B), A and B side "
                             "by side (S), or a wipe between them (W)"));
  bar->addWidget(layout_box_);
  connect(layout_box_, &QComboBox::currentIndexChanged, this, [this](int i) {
    constexpr ImageCanvas::Layout layouts[] = {ImageCanvas::Layout::SideBySide, ImageCanvas::Layout::Single,
                                               ImageCanvas::Layout::Pair, ImageCanvas::Layout::Wipe};
    canvas_->setLayout(layouts[std::clamp(i, 0, 3)]);
  });
  aov_box_ = new QComboBox(this);
  aov_box_->setObjectName("aovBox");
  for (AovRole v : kViewableAovs) aov_box_->addItem(display_name(v), static_cast<int>(v));
  aov_box_->setToolTip(tr("The AOV the noisy pane shows ([ and ])"));
  bar->addWidget(aov_box_);
  connect(aov_box_, &QComboBox::currentIndexChanged, this,
          [this] { setAov(static_cast<AovRole>(aov_box_->currentData().toInt())); });

  exposure_box_ = new QDoubleSpinBox(this);
  exposure_box_->setObjectName("exposureBox");
  exposure_box_->setRange(-20, 20);
  exposure_box_->setSingleStep(0.5);
  exposure_box_->setDecimals(1);
  exposure_box_->setToolTip(tr("Exposure in stops (E / Shift+E)"));
  exposure_box_->setPrefix(tr("EV "));
  bar->addWidget(exposure_box_);
  offset_box_ = new QDoubleSpinBox(this);
  offset_box_->setObjectName("offsetBox");
  offset_box_->setRange(-10, 10);
  offset_box_->setSingleStep(0.01);
  offset_box_->setDecimals(3);
  offset_box_->setToolTip(tr("Offset added after the exposure"));
  offset_box_->setPrefix(tr("+ "));
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
  action(file, tr("&Add Result..."), QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_A), [this] {
    const QStringList files = QFileDialog::getOpenFileNames(this, tr("Add results to compare"), QString(),
                                                            tr("Images (*.exr *.hdr *.pfm *.tif *.tiff *.png);;All files (*)"));
    addResultFiles(files);
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
  action(exp, tr("Export &All..."), QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_E), [this] { exportAllDialog(); });
  exp->addSeparator();
  action(exp, tr("Denoised image (EXR)..."), QKeySequence(Qt::CTRL | Qt::Key_E), [this] {
    if (!session_->denoised()) return void(QMessageBox::information(this, tr("Export"), tr("Denoise first.")));
    // Pixel type and compression, as residue-cli offers them.
    QDialog dlg(this);
    dlg.setWindowTitle(tr("EXR options"));
    auto* form = new QFormLayout(&dlg);
    auto* type = new QComboBox(&dlg);
    type->addItems({"half", "float"});
    auto* comp = new QComboBox(&dlg);
    for (const auto& c : io::exr_compressions()) comp->addItem(QString::fromStdString(c));
    comp->setCurrentText("zip");
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
  action(exp, tr("Comparison sheet (PNG)..."), QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_S), [this] {
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
  action(view, tr("All panes"), QKeySequence(Qt::Key_A), [this] { layout_box_->setCurrentIndex(0); });
  action(view, tr("A | B side by side"), QKeySequence(Qt::Key_S), [this] { layout_box_->setCurrentIndex(2); });
  action(view, tr("Wipe A | B"), QKeySequence(Qt::Key_W), [this] { layout_box_->setCurrentIndex(3); });
  action(view, tr("Flip A / B"), QKeySequence(Qt::Key_Space), [this] {
    if (canvas_->layout() != ImageCanvas::Layout::Single) canvas_->setCurrent(canvas_->wipeA());
    layout_box_->setCurrentIndex(1);
    canvas_->flipAB();
  });
  action(view, tr("Difference: A against B"), QKeySequence(Qt::Key_D), [this] {
    if (session_->b() < 0) return statusBar()->showMessage(tr("Pick a result B first (Ctrl+1-9)"), 5000);
    heatmap_->setOf(HeatmapPanel::Of::AgainstB);
    heatmap_->setDisplay(HeatmapPanel::Display::Pane);
    tabs_->setCurrentWidget(heatmap_);
    if (paneIndex(Source::Heatmap) >= 0) showPane(Source::Heatmap);
    else pending_pane_ = Source::Heatmap;  // once the panes are drawn with it
  });
  auto* next = action(view, tr("Next pane"), QKeySequence(Qt::Key_Tab), [this] { cyclePane(+1); });
  next->setShortcutContext(Qt::ApplicationShortcut);
  auto* prev = action(view, tr("Previous pane"), QKeySequence(Qt::SHIFT | Qt::Key_Backtab), [this] { cyclePane(-1); });
  prev->setShortcuts({QKeySequence(Qt::SHIFT | Qt::Key_Backtab), QKeySequence(Qt::Key_Backtab)});
  auto* pick = view->addMenu(tr("Wipe pair"));
  const Source pairable[] = {Source::Noisy, Source::Denoised, Source::Compare, Source::Reference};
  for (Source sa : pairable) {
    for (Source sb : pairable) {
      if (sb <= sa) continue;
      const auto label = [](Source x) { return x == Source::Denoised ? QString("A") : x == Source::Compare ? QString("B")
                                                                                       : QString::fromLatin1(to_string(x)); };
      action(pick, QString("%1 | %2").arg(label(sa), label(sb)), QKeySequence(), [this, sa, sb] {
        setWipePair(sa, sb);
        layout_box_->setCurrentIndex(3);
      });
    }
  }
  view->addSeparator();
  auto* results = view->addMenu(tr("Results"));
  for (int i = 1; i <= 9; ++i) {
    action(results, tr("Result %1 as A").arg(i), QKeySequence(Qt::Key_0 + i), [this, i] { pickResult(i - 1, false); });
    action(results, tr("Result %1 as B").arg(i), QKeySequence(Qt::CTRL | (Qt::Key_0 + i)), [this, i] { pickResult(i - 1, true); });
  }
  action(view, tr("Side Bar"), QKeySequence(Qt::Key_F9), [this] {
    if (auto* d = findChild<QDockWidget*>("sideDock")) d->setVisible(!d->isVisible());
  });
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

void MainWindow::addResultFiles(const QStringList& files) {
  if (files.isEmpty()) return;
  if (!session_->hasStack()) {
    last_error_ = tr("Open a render before adding results to compare with it.");
    if (interactive_) QMessageBox::information(this, tr("Add Result"), last_error_);
    return;
  }
  tabs_->setCurrentWidget(metrics_);
  for (const auto& f : files) session_->addResultFile(f.toStdString());
}

bool MainWindow::looksLikeResult(const QString& file) const {
  const auto stack = session_->stack();
  if (!stack) return false;
  auto in = OIIO::ImageInput::open(file.toStdString());
  if (!in) return false;
  const auto& spec = in->spec();
  return spec.width == stack->width() && spec.height == stack->height() && spec.nchannels <= 4 &&
         in->current_subimage() == 0 && !in->seek_subimage(1, 0);
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
  layout_box_->setCurrentIndex(layout == ImageCanvas::Layout::SideBySide ? 0
                               : layout == ImageCanvas::Layout::Single   ? 1
                               : layout == ImageCanvas::Layout::Pair     ? 2
                                                                         : 3);
}

void MainWindow::setWipePair(Source a, Source b) {
  wipe_a_ = a;
  wipe_b_ = b;
  // What is not shown falls back: B to the reference to the noisy input; A to the noisy input.
  const auto shown = [this](Source s, std::initializer_list<Source> fallbacks, int not_this) {
    if (const int i = paneIndex(s); i >= 0 && i != not_this) return i;
    for (Source f : fallbacks)
      if (const int i = paneIndex(f); i >= 0 && i != not_this) return i;
    return -1;
  };
  const int ia = shown(a, {Source::Denoised, Source::Noisy}, -1);
  const int ib = shown(b, {Source::Compare, Source::Reference, Source::Noisy, Source::Denoised}, ia);
  if (ia >= 0 && ib >= 0) canvas_->setWipePair(ia, ib);
}

void MainWindow::cyclePane(int step) {
  const int n = static_cast<int>(canvas_->panes().size());
  if (n == 0) return;
  if (canvas_->layout() == ImageCanvas::Layout::Single) canvas_->setCurrent((canvas_->current() + step + n) % n);
  layout_box_->setCurrentIndex(1);
  statusBar()->showMessage(canvas_->panes()[static_cast<size_t>(canvas_->current())].label, 3000);
}

void MainWindow::pickResult(int index, bool as_b) {
  const auto& results = session_->results();
  if (index < 0 || index >= static_cast<int>(results.size())) {
    statusBar()->showMessage(tr("There is no result %1 (the Results tab lists them)").arg(index + 1), 4000);
    return;
  }
  const int id = results[static_cast<size_t>(index)].id;
  if (as_b) session_->setB(id);
  else session_->setA(id);
  statusBar()->showMessage(tr("%1: %2").arg(as_b ? "B" : "A", results[static_cast<size_t>(index)].name), 4000);
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
  if (s == Source::Compare) return session_->compareShared();  // a result's, not the stack's
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
  if (session_->b() >= 0) pane_sources_.push_back(Source::Compare);
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
  const bool a_running = denoise_->controller()->runningResult() == session_->a() && session_->a() >= 0;
  in.denoised = a_running && denoise_->runningFromNoisy() ? shared(Source::Noisy) : session_->denoisedShared();
  in.compare = session_->compareShared();
  in.reference = shared(Source::Reference);
  in.heat_image = heatmap_->image();
  in.heat_map = heatmap_->map();
  in.heat_title = heatmap_->title();
  const auto label = [this](int id) {
    const Result* r = session_->result(id);
    if (!r) return QString();
    QString text = session_->resultName(id);
    if (!r->state.isEmpty()) text += " (" + r->state + ")";
    return text;
  };
  in.a_name = label(session_->a());
  in.b_name = label(session_->b());
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
  MetricsPanel::Row noisy;
  noisy.name = tr("noisy input");
  noisy.file = QString::fromStdString(stack->color.source.file);
  noisy.image = shared(Source::Noisy);
  in.rows.push_back(noisy);
  const int running = denoise_->controller()->runningResult();
  for (const auto& r : session_->results()) {
    MetricsPanel::Row row;
    row.id = r.id;
    row.name = session_->resultName(r.id);
    row.file = r.description;
    // A result still being made is listed without scores: its pixels are half noisy.
    if (r.id != running) row.image = r.id == session_->a() ? session_->denoisedShared() : r.image;
    row.seconds = r.seconds;
    row.state = r.state;
    row.a = r.id == session_->a();
    row.b = r.id == session_->b();
    in.rows.push_back(std::move(row));
  }
  in.reference = shared(Source::Reference);
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
  const QString a_name = session_->resultName(session_->a()), b_name = session_->resultName(session_->b());
  const auto a_image = running == session_->a() ? nullptr : session_->denoisedShared();
  const auto b_image = running == session_->b() ? nullptr : session_->compareShared();
  switch (heatmap_->of()) {
    case HeatmapPanel::Of::A:
      heatmap_->compute(a_image, in.reference, a_name.isEmpty() ? tr("A") : a_name,
                        !in.reference ? tr("no reference") : tr("no result A yet (denoise, or add a result)"),
                        metrics_->options());
      break;
    case HeatmapPanel::Of::B:
      heatmap_->compute(b_image, in.reference, b_name.isEmpty() ? tr("B") : b_name,
                        !in.reference ? tr("no reference") : tr("no result B (Ctrl+1-9 picks one)"), metrics_->options());
      break;
    case HeatmapPanel::Of::Noisy:
      heatmap_->compute(in.rows.front().image, in.reference, tr("the noisy input"), tr("no reference"),
                        metrics_->options());
      break;
    case HeatmapPanel::Of::AgainstB:
      heatmap_->compute(a_image, b_image, tr("%1 against %2").arg(a_name, b_name),
                        tr("needs a result A and a result B (Ctrl+1-9)"), metrics_->options());
      break;
  }
}

void MainWindow::applyHeatmap() {
  canvas_->clearOverlays();
  const auto d = heatmap_->display();
  if (d == HeatmapPanel::Display::Pane) {
    const int i = paneIndex(Source::Heatmap);
    if (i >= 0) {
      canvas_->setPaneDisplay(i, heatmap_->image());
      canvas_->setPaneValues(i, heatmap_->map());
      canvas_->setPaneLabel(i, heatmap_->title());  // the map may be newer than the panes
    }
  } else if (d == HeatmapPanel::Display::Overlay) {
    const int i = paneIndex(heatmap_->of() == HeatmapPanel::Of::Noisy ? Source::Noisy
                            : heatmap_->of() == HeatmapPanel::Of::B  ? Source::Compare
                                                                     : Source::Denoised);
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
  const QString name = session_->resultName(session_->a());
  const QString description = session_->denoisedDescription();
  const float strength = session_->strength();
  return QtConcurrent::run([=]() -> QString {
    if (!denoised || !stack) return tr("Nothing to export: no denoised image.");
    try {
      write_result_exr(path.toStdString(), *denoised, *stack, name, description, overwrite, half,
                       compression.toStdString(), strength);
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
  };
  std::vector<Item> items;
  std::shared_ptr<const DisplayTransform> display;
  DisplaySettings settings;
  SheetOptions options;

  QImage draw() const {
    std::vector<SheetPanel> panels;
    for (const auto& it : items) {
      SheetPanel p{it.label, {}, it.lines};
      try {
        if (it.image) p.image = display->render(*it.image, 0, 3, it.image->bounds(), settings, Encoding::SceneLinear);
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
  const auto& report = metrics_->wholeReport();
  const auto scores = [&](const QString& name) {
    for (const auto& row : report.rows)
      if (QString::fromStdString(row.name) == name)
        return QStringList{QString("relMSE %1   SSIM %2").arg(row.scores.relmse, 0, 'g', 4).arg(row.scores.ssim, 0, 'f', 4),
                           QString("PSNR %1 dB").arg(row.scores.psnr, 0, 'f', 2)};
    return QStringList{};
  };
  in.items.push_back({tr("Noisy input"), shared(Source::Noisy), scores("noisy")});
  for (const auto& r : session_->results()) {
    const QString name = session_->resultName(r.id);
    QStringList lines = scores(name);
    if (r.seconds > 0 && !lines.isEmpty()) lines.back() += tr("   %1 s here").arg(r.seconds, 0, 'f', 2);
    else if (r.seconds > 0) lines << tr("%1 s here").arg(r.seconds, 0, 'f', 2);
    if (!r.state.isEmpty()) lines << r.state;
    in.items.push_back({name, r.id == session_->a() ? session_->denoisedShared() : r.image, lines});
  }
  if (const auto ref = shared(Source::Reference)) in.items.push_back({tr("Reference"), ref, {}});
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

QFuture<QString> MainWindow::exportAll(const QString& folder, bool overwrite) {
  ExportAllInputs in;
  in.stack = session_->stack();
  for (const auto& r : session_->results()) {
    if (r.id == denoise_->controller()->runningResult()) continue;
    Result copy = r;
    copy.name = session_->resultName(r.id);
    if (r.id == session_->a()) {  // as shown: at its strength
      copy.image = std::const_pointer_cast<Image>(session_->denoisedShared());
      copy.description = session_->denoisedDescription();
    }
    in.results.push_back(std::move(copy));
  }
  in.reference = shared(Source::Reference);
  in.options = metrics_->options();
  in.map_kind = heatmap_->kind();
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

void MainWindow::exportAllDialog() {
  if (!session_->hasStack()) return void(QMessageBox::information(this, tr("Export All"), tr("Open a render first.")));
  QSettings settings;
  const QString start = settings.value("exportFolder", QDir::homePath() + "/residue-export").toString();
  const QString folder = QFileDialog::getExistingDirectory(this, tr("Export all into a folder"),
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
  probe.sheet = [] { return QImage(); };
  QStringList existing;
  for (const auto& f : planned_files(probe, folder.toStdString()))
    if (std::filesystem::exists(f)) existing << QString::fromStdString(f.filename().string());
  bool overwrite = false;
  if (!existing.isEmpty()) {
    if (QMessageBox::question(this, tr("Export All"),
                              tr("%1 already holds %n of these file(s):\n%2\n\nReplace them?", nullptr,
                                 static_cast<int>(existing.size()))
                                  .arg(folder, existing.mid(0, 12).join("\n") + (existing.size() > 12 ? "\n..." : "")),
                              QMessageBox::Yes | QMessageBox::Cancel, QMessageBox::Cancel) != QMessageBox::Yes)
      return;
    overwrite = true;
  }
  runExport(tr("export into %1").arg(folder), exportAll(folder, overwrite));
}

}  // namespace residue::ui
