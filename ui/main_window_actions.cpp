// MainWindow's furniture: the side bar of tabs, the toolbar, the menus with their actions and shortcuts, and the
// shortcut table the help overlay lists.
#include "ui/main_window.h"

#include <QAction>
#include <QApplication>
#include <QClipboard>
#include <QGuiApplication>
#include <QComboBox>
#include <QDialog>
#include <QDialogButtonBox>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QFormLayout>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <QStatusBar>
#include <QTabWidget>
#include <QToolBar>
#include <QVBoxLayout>

#include "core/io/exr_writer.h"
#include "core/util/error.h"
#include "ui/denoise_panel.h"
#include "ui/help_overlay.h"
#include "ui/histogram.h"
#include "ui/mapping_dialog.h"
#include "ui/metrics_panel.h"
#include "ui/pane_renderer.h"
#include "ui/pixel_inspector.h"
#include "ui/recent_renders.h"
#include "ui/render_list.h"
#include "ui/tev_server.h"

namespace residue::ui {

// What the Open dialogs list: what OpenImageIO reads for a render, a reference or a result.
const QString MainWindow::kImageFilter = QStringLiteral(
    "Images (*.exr *.hdr *.pfm *.tif *.tiff *.png *.jpg *.jpeg);;OpenEXR (*.exr);;All files (*)");

QString MainWindow::startFolder() const {
  if (!session_->inputs().empty()) {
    const QFileInfo first(QString::fromStdString(session_->inputs().front().string()));
    return first.isDir() ? first.absoluteFilePath() : first.absolutePath();
  }
  const auto recent = RecentRenders().list();
  if (!recent.empty()) return QFileInfo(recent.front().inputs.front()).absolutePath();
  return {};
}

// The help overlay's rows come from the actions themselves: each action's `help` text, with its shortcuts (actions
// that share a text share a row: "E  Shift+E"), then what the mouse does. A key is written once, where it is bound.
std::vector<std::pair<QString, QString>> MainWindow::shortcutRows() const {
  std::vector<std::pair<QString, QString>> rows;
  for (const QAction* a : actions()) {
    const QString what = a->property("help").toString();
    if (what.isEmpty()) continue;
    QString keys = a->property("helpKeys").toString();
    if (keys.isEmpty()) keys = a->shortcut().toString(QKeySequence::NativeText);
    const auto it = std::find_if(rows.begin(), rows.end(), [&](const auto& r) { return r.second == what; });
    if (it == rows.end()) rows.emplace_back(keys, what);
    else if (!a->property("helpKeys").isValid() && !it->first.contains(keys)) it->first += "  " + keys;
  }
  for (const auto& [keys, what] : std::initializer_list<std::pair<QString, QString>>{
           {tr("Esc"), tr("stop playing, cancel, close help")},
           {tr("drag"), tr("pan")},
           {tr("Shift+drag, right-drag"), tr("region of interest")}})
    rows.emplace_back(keys, what);
  return rows;
}

void MainWindow::buildDocks() {
  // One side bar of tabs: the canvas keeps most of the window, and the bar can be closed (View > Side Bar).
  denoise_ = new DenoisePanel(session_, this);
  metrics_ = new MetricsPanel(this);
  heatmap_ = new HeatmapPanel(this);
  inspector_ = new PixelInspector(this);
  render_list_ = new RenderList(session_, this);
  tabs_ = new QTabWidget(this);
  tabs_->setObjectName("sideTabs");
  tabs_->addTab(render_list_, tr("Renders"));
  tabs_->addTab(metrics_, tr("Results"));
  tabs_->addTab(denoise_, tr("Denoise"));
  tabs_->addTab(heatmap_, tr("Heatmap"));
  // The Pixel tab: the values under the cursor, and how the image under it is spread (its luminance, on a log
  // axis: tev's and HDRView's image histogram).
  pixel_page_ = new QWidget(this);
  auto* pixel_layout = new QVBoxLayout(pixel_page_);
  pixel_layout->setContentsMargins(0, 0, 0, 0);
  pixel_layout->addWidget(inspector_, 1);
  image_histogram_ = new Histogram(pixel_page_);
  image_histogram_->setObjectName("imageHistogram");
  image_histogram_->setMinimumHeight(140);
  pixel_layout->addWidget(image_histogram_);
  tabs_->addTab(pixel_page_, tr("Pixel"));
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
  // Every control says what it is: a label before it (its buddy, for Alt+letter), not only a tooltip.
  const auto labelled = [this, bar](const QString& text, QWidget* control) {
    auto* label = new QLabel(text, this);
    label->setBuddy(control);
    label->setContentsMargins(8, 0, 4, 0);
    bar->addWidget(label);
    bar->addWidget(control);
  };
  layout_box_ = new QComboBox(this);
  layout_box_->setObjectName("layoutBox");
  layout_box_->addItems({tr("All"), tr("Single"), tr("A | B"), tr("Wipe A | B")});
  layout_box_->setToolTip(tr("All panes in a grid (A), one pane (Tab cycles, Space flips A and B), A and B side "
                             "by side (S), or a wipe between them (W)"));
  labelled(tr("&Layout"), layout_box_);
  connect(layout_box_, &QComboBox::currentIndexChanged, this, [this](int i) {
    constexpr ImageCanvas::Layout layouts[] = {ImageCanvas::Layout::SideBySide, ImageCanvas::Layout::Single,
                                               ImageCanvas::Layout::Pair, ImageCanvas::Layout::Wipe};
    canvas_->setLayout(layouts[std::clamp(i, 0, 3)]);
  });
  aov_box_ = new QComboBox(this);
  aov_box_->setObjectName("aovBox");
  for (AovRole v : kViewableAovs) aov_box_->addItem(display_name(v), static_cast<int>(v));
  aov_box_->setToolTip(tr("What the noisy pane shows: an AOV, or any other layer of the render's files ([ and ])"));
  labelled(tr("&AOV"), aov_box_);
  connect(aov_box_, &QComboBox::currentIndexChanged, this, [this](int i) { showBoxItem(i); });

  channel_box_ = new QComboBox(this);
  channel_box_->setObjectName("channelBox");
  for (DisplayChannel c : {DisplayChannel::RGB, DisplayChannel::R, DisplayChannel::G, DisplayChannel::B,
                           DisplayChannel::Luminance}) {
    const QString names[] = {tr("RGB"), tr("R"), tr("G"), tr("B"), tr("Luminance")};
    channel_box_->addItem(names[static_cast<int>(c)], static_cast<int>(c));
  }
  channel_box_->setToolTip(tr("Every pane's colour, or one channel of it alone as grey (Rec. 709 luminance: Y)"));
  labelled(tr("&Channel"), channel_box_);
  connect(channel_box_, &QComboBox::currentIndexChanged, this, &MainWindow::refreshPanes);

  exposure_box_ = new QDoubleSpinBox(this);
  exposure_box_->setObjectName("exposureBox");
  exposure_box_->setRange(-20, 20);
  exposure_box_->setSingleStep(0.5);
  exposure_box_->setDecimals(1);
  exposure_box_->setToolTip(tr("Exposure in stops (E / Shift+E)"));
  exposure_box_->setSuffix(tr(" EV"));
  labelled(tr("E&xposure"), exposure_box_);
  offset_box_ = new QDoubleSpinBox(this);
  offset_box_->setObjectName("offsetBox");
  offset_box_->setRange(-10, 10);
  offset_box_->setSingleStep(0.01);
  offset_box_->setDecimals(3);
  offset_box_->setToolTip(tr("Offset added after the exposure"));
  labelled(tr("Off&set"), offset_box_);
  gamma_box_ = new QDoubleSpinBox(this);
  gamma_box_->setObjectName("gammaBox");
  gamma_box_->setRange(0.1, 10);
  gamma_box_->setSingleStep(0.1);
  gamma_box_->setDecimals(2);
  gamma_box_->setValue(1.0);
  gamma_box_->setToolTip(tr("Gamma after the view: display values v are shown as v^(1/gamma); above 1 opens the "
                            "shadows (R resets it)"));
  labelled(tr("&Gamma"), gamma_box_);
  connect(exposure_box_, &QDoubleSpinBox::valueChanged, this, &MainWindow::refreshPanes);
  connect(offset_box_, &QDoubleSpinBox::valueChanged, this, &MainWindow::refreshPanes);
  connect(gamma_box_, &QDoubleSpinBox::valueChanged, this, &MainWindow::refreshPanes);

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
  labelled(tr("Displa&y"), display_box_);
  labelled(tr("Vie&w"), view_box_);
  display_box_->setToolTip(tr("OpenColorIO display and view (%1)").arg(QString::fromStdString(display_->source())));
  view_box_->setToolTip(display_box_->toolTip());
}

namespace {
// Lists an action's shortcut in the help overlay as `help`; `keys`, when given, is what it shows for the keys (a
// range of actions: "1 - 9").
QAction* listed(QAction* a, const QString& help, const QString& keys = QString()) {
  a->setProperty("help", help);
  if (!keys.isEmpty()) a->setProperty("helpKeys", keys);
  return a;
}
}  // namespace

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
  listed(action(file, tr("&Open..."), QKeySequence::Open, [this] {
    const QStringList files = QFileDialog::getOpenFileNames(this, tr("Open a render (AOV stack)"), startFolder(),
                                                            kImageFilter);
    if (!files.isEmpty()) openFiles(files);
  }), tr("open a render / open its reference"));
  listed(action(file, tr("Open &Reference..."), QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_O), [this] {
    const QString f = QFileDialog::getOpenFileName(this, tr("Open a reference image"), startFolder(), kImageFilter);
    if (!f.isEmpty()) openReferenceFile(f);
  }), tr("open a render / open its reference"));
  listed(action(file, tr("&Add Result..."), QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_A), [this] {
    const QStringList files = QFileDialog::getOpenFileNames(this, tr("Add results to compare"), startFolder(), kImageFilter);
    addResultFiles(files);
  }), tr("add a result to compare (or drop it)"));
  listed(action(file, tr("Previous Render"), QKeySequence(Qt::Key_PageUp), [this] { stepRender(-1); }), tr("previous / next open render"));
  listed(action(file, tr("Next Render"), QKeySequence(Qt::Key_PageDown), [this] { stepRender(+1); }), tr("previous / next open render"));
  listed(action(file, tr("Close Render"), QKeySequence(Qt::CTRL | Qt::Key_W), [this] {
    session_->closeRender(session_->currentRender());
  }), tr("close the render shown (its results go with it)"));
  recent_menu_ = file->addMenu(tr("Open Re&cent"));
  recent_menu_->setObjectName("recentMenu");
  recent_menu_->setToolTipsVisible(true);  // the full paths and the reference
  listed(action(file, tr("Re&load"), QKeySequence(Qt::Key_F5), [this] { session_->reload(); }), tr("reload"));
  auto_reload_ = action(file, tr("Reload When the Files Change"), QKeySequence(), [this] { watchInputs(); });
  auto_reload_->setCheckable(true);
  auto_reload_->setChecked(true);
  live_denoise_ = action(file, tr("Denoise Streamed Images When They Pause"), QKeySequence(), [] {});
  live_denoise_->setCheckable(true);
  live_denoise_->setChecked(true);
  file->addSeparator();
  auto* exp = file->addMenu(tr("&Export"));
  listed(action(exp, tr("Export &All..."), QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_E), [this] { exportAllDialog(); }), tr("export all"));
  action(exp, tr("The &Region: Each Result's Crop and Scores..."), QKeySequence(), [this] { exportAllDialog(true); });
  listed(action(exp, tr("The &View (PNG)..."), QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_P), [this] {
    const QString path = askSavePath(tr("Save the view"), tr("PNG (*.png)"), "png");
    if (!path.isEmpty()) runExport(tr("view PNG"), exportView(path, true));
  }), tr("save the view as PNG / copy it"));
  listed(action(exp, tr("&Copy the View"), QKeySequence(Qt::CTRL | Qt::Key_C), [this] {
    QGuiApplication::clipboard()->setImage(canvas_->grab().toImage());
    say(tr("The view is on the clipboard (%1 x %2)").arg(canvas_->width()).arg(canvas_->height()), 4000);
  }), tr("save the view as PNG / copy it"));
  exp->addSeparator();
  listed(action(exp, tr("Denoised image (EXR)..."), QKeySequence(Qt::CTRL | Qt::Key_E), [this] {
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
  }), tr("export the denoised EXR"));
  action(exp, tr("Heatmap (PNG)..."), QKeySequence(), [this] {
    const QString path = askSavePath(tr("Export the heatmap"), tr("PNG (*.png)"), "png");
    if (!path.isEmpty()) runExport(tr("heatmap PNG"), exportHeatmap(path, true));
  });
  action(exp, tr("Heatmap values (EXR)..."), QKeySequence(), [this] {
    const QString path = askSavePath(tr("Export the heatmap values"), tr("OpenEXR (*.exr)"), "exr");
    if (!path.isEmpty()) runExport(tr("heatmap EXR"), exportHeatmap(path, true));
  });
  listed(action(exp, tr("Comparison sheet (PNG)..."), QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_S), [this] {
    const QString path = askSavePath(tr("Export the comparison"), tr("PNG (*.png)"), "png");
    if (!path.isEmpty()) runExport(tr("comparison PNG"), exportComparison(path, true));
  }), tr("export the comparison sheet (PNG)"));
  action(exp, tr("Metrics (JSON or CSV)..."), QKeySequence(), [this] {
    const QString path = askSavePath(tr("Export the metrics"), tr("JSON (*.json);;CSV (*.csv)"), "json");
    if (!path.isEmpty()) runExport(tr("metrics"), exportMetrics(path, true));
  });
  file->addSeparator();
  listed(action(file, tr("&Quit"), QKeySequence(Qt::CTRL | Qt::Key_Q), [this] { close(); }), tr("quit"));

  auto* view = menuBar()->addMenu(tr("&View"));
  listed(action(view, tr("All panes"), QKeySequence(Qt::Key_A), [this] { layout_box_->setCurrentIndex(0); }), tr("all panes, in a grid"));
  listed(action(view, tr("A | B side by side"), QKeySequence(Qt::Key_S), [this] { layout_box_->setCurrentIndex(2); }), tr("A and B side by side"));
  listed(action(view, tr("Wipe A | B"), QKeySequence(Qt::Key_W), [this] { layout_box_->setCurrentIndex(3); }), tr("wipe A | B (drag the line)"));
  listed(action(view, tr("Flip A / B"), QKeySequence(Qt::Key_Space), [this] {
    if (canvas_->layout() != ImageCanvas::Layout::Single) canvas_->setCurrent(canvas_->wipeA());
    layout_box_->setCurrentIndex(1);
    canvas_->flipAB();
  }), tr("flip between A and B"));
  listed(action(view, tr("Difference: A against B"), QKeySequence(Qt::Key_D), [this] {
    if (session_->b() < 0) return say(tr("Pick a result B first (Ctrl+1-9)"), 5000);
    heatmap_->setOf(HeatmapPanel::Of::AgainstB);
    heatmap_->setKind(metrics::MapKind::SignedDifference);  // A - B, blue where A is darker, red where brighter
    heatmap_->setDisplay(HeatmapPanel::Display::Pane);
    tabs_->setCurrentWidget(heatmap_);
    if (paneIndex(Source::Heatmap) >= 0) showPane(Source::Heatmap);
    else pending_pane_ = Source::Heatmap;  // once the panes are drawn with it
  }), tr("difference: A - B, signed"));
  auto* next = listed(action(view, tr("Next pane"), QKeySequence(Qt::Key_Tab), [this] { cyclePane(+1); }), tr("single layout: next / previous pane"), tr("Tab  Shift+Tab"));
  next->setShortcutContext(Qt::ApplicationShortcut);
  auto* prev = listed(action(view, tr("Previous pane"), QKeySequence(Qt::SHIFT | Qt::Key_Tab), [this] { cyclePane(-1); }), tr("single layout: next / previous pane"), tr("Tab  Shift+Tab"));
  // Shift+Tab arrives as Backtab (with or without Shift, by platform); the menu shows the first, as a user types it.
  prev->setShortcuts({QKeySequence(Qt::SHIFT | Qt::Key_Tab), QKeySequence(Qt::SHIFT | Qt::Key_Backtab), QKeySequence(Qt::Key_Backtab)});
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
    listed(action(results, tr("Result %1 as A").arg(i), QKeySequence(Qt::Key_0 + i), [this, i] { pickResult(i - 1, false); }), tr("result 1-9 (Results tab rows) as A"), tr("1 - 9"));
    listed(action(results, tr("Result %1 as B").arg(i), QKeySequence(Qt::CTRL | (Qt::Key_0 + i)), [this, i] { pickResult(i - 1, true); }), tr("result 1-9 as B"), tr("Ctrl+1 - 9"));
  }
  auto* themes = view->addMenu(tr("&Theme"));
  for (Theme t : {Theme::System, Theme::Light, Theme::Dark}) {
    const QString names[] = {tr("As the System"), tr("Light"), tr("Dark")};
    QAction* a = action(themes, names[static_cast<int>(t)], QKeySequence(), [this, t] { setTheme(t); });
    a->setCheckable(true);
    a->setChecked(t == theme_);
    a->setData(static_cast<int>(t));
    theme_actions_.push_back(a);
  }
  listed(action(view, tr("Side Bar"), QKeySequence(Qt::Key_F9), [this] {
    if (auto* d = findChild<QDockWidget*>("sideDock")) d->setVisible(!d->isVisible());
  }), tr("hide / show the side bar"));
  view->addSeparator();
  listed(action(view, tr("Fit"), QKeySequence(Qt::Key_F), [this] { canvas_->fit(); }), tr("fit"));
  listed(action(view, tr("1:1"), QKeySequence(Qt::CTRL | Qt::Key_0), [this] { canvas_->oneToOne(); }), tr("1:1 (a pixel per screen pixel)"));
  listed(action(view, tr("1:1 Device Pixels"), QKeySequence(Qt::ALT | Qt::Key_0), [this] {
    canvas_->setView(1.0 / canvas_->devicePixelRatioF(), canvas_->center());
  }), tr("1:1 in device pixels (a scaled screen)"));
  // Half a stop of zoom a key press, as the wheel's notches come in quarters: x2 jumped past what one wanted.
  auto* zin = listed(action(view, tr("Zoom in"), QKeySequence(Qt::Key_Plus), [this] { canvas_->zoomBy(ImageCanvas::kZoomStep); }),
                     tr("zoom (the wheel: about the cursor)"), tr("+  -  wheel"));
  zin->setShortcuts({QKeySequence(Qt::Key_Plus), QKeySequence(Qt::Key_Equal), QKeySequence::ZoomIn});
  auto* zout = listed(action(view, tr("Zoom out"), QKeySequence(Qt::Key_Minus), [this] { canvas_->zoomBy(1.0 / ImageCanvas::kZoomStep); }),
                      tr("zoom (the wheel: about the cursor)"), tr("+  -  wheel"));
  zout->setShortcuts({QKeySequence(Qt::Key_Minus), QKeySequence::ZoomOut});
  view->addSeparator();
  listed(action(view, tr("Exposure +1/2 stop"), QKeySequence(Qt::Key_E), [this] { setExposure(exposure() + 0.5); }), tr("exposure up / down half a stop"));
  listed(action(view, tr("Exposure -1/2 stop"), QKeySequence(Qt::SHIFT | Qt::Key_E), [this] { setExposure(exposure() - 0.5); }), tr("exposure up / down half a stop"));
  listed(action(view, tr("Reset exposure, offset and gamma"), QKeySequence(Qt::Key_R), [this] {
    setExposure(0);
    offset_box_->setValue(0);
    gamma_box_->setValue(1.0);
  }), tr("reset exposure, offset and gamma"));
  clipping_ = listed(action(view, tr("Clipping Warning"), QKeySequence(Qt::Key_C), [this] { refreshPanes(); }),
                     tr("clipping warning / false colour"));
  clipping_->setCheckable(true);
  false_colour_ = listed(action(view, tr("False Colour"), QKeySequence(Qt::SHIFT | Qt::Key_C), [this] {
    if (false_colour_->isChecked())
      say(tr("False colour: luminance in stops about mid grey (0.18), from dark blue at -6.5 through green at 0 to "
             "dark red at +6.5 (turbo); Shift+C again for the view"), 10000);
    refreshPanes();
  }),
                         tr("clipping warning / false colour"));
  false_colour_->setCheckable(true);
  listed(action(view, tr("Previous AOV"), QKeySequence(Qt::Key_BracketLeft), [this] { cycleAov(-1); }), tr("previous / next AOV or layer"));
  listed(action(view, tr("Next AOV"), QKeySequence(Qt::Key_BracketRight), [this] { cycleAov(+1); }), tr("previous / next AOV or layer"));
  listed(action(view, tr("Heatmap: pane / overlay / off"), QKeySequence(Qt::Key_H), [this] {
    const auto d = heatmap_->display();
    heatmap_->setDisplay(d == HeatmapPanel::Display::Pane      ? HeatmapPanel::Display::Overlay
                         : d == HeatmapPanel::Display::Overlay ? HeatmapPanel::Display::Off
                                                               : HeatmapPanel::Display::Pane);
  }), tr("heatmap: own pane / overlay / off"));
  listed(action(view, tr("Clear region of interest"), QKeySequence(Qt::Key_Backspace), [this] { setRoi(std::nullopt); }), tr("clear the region of interest"));

  auto* den = menuBar()->addMenu(tr("&Denoise"));
  listed(action(den, tr("&Denoise"), QKeySequence(Qt::CTRL | Qt::Key_D), [this] { denoise_->start(); }), tr("denoise with the selected model"));
  listed(action(den, tr("Denoise &Every Frame"), QKeySequence(Qt::CTRL | Qt::SHIFT | Qt::Key_D), [this] { denoiseEveryFrame(); }), tr("denoise every frame"));
  // Esc is the window's (keyPressEvent: it stops playing or closes the help first); the menu names it after a tab.
  action(den, tr("&Cancel") + '\t' + tr("Esc"), QKeySequence(), [this] { denoise_->cancel(); });

  auto* frames = menuBar()->addMenu(tr("F&rames"));
  listed(action(frames, tr("&Previous Frame"), QKeySequence(Qt::Key_Left), [this] { stepFrame(-1); }), tr("previous / next frame"));
  listed(action(frames, tr("&Next Frame"), QKeySequence(Qt::Key_Right), [this] { stepFrame(+1); }), tr("previous / next frame"));
  listed(action(frames, tr("&First Frame"), QKeySequence(Qt::Key_Home), [this] {
    if (const auto& s = session_->sequence()) goToFrame(s->frames.front());
  }), tr("first / last frame"));
  listed(action(frames, tr("&Last Frame"), QKeySequence(Qt::Key_End), [this] {
    if (const auto& s = session_->sequence()) goToFrame(s->frames.back());
  }), tr("first / last frame"));
  listed(action(frames, tr("P&lay / Pause"), QKeySequence(Qt::Key_P), [this] { setPlaying(!playing_); }), tr("play / pause the frames"));

  auto* help = menuBar()->addMenu(tr("&Help"));
  auto* keys = listed(action(help, tr("Keyboard shortcuts"), QKeySequence(Qt::Key_Question), [this] { help_->toggle(); }), tr("this help"), tr("?  F1"));
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

}  // namespace residue::ui
