#include "ui/main_window.h"

#include <QAbstractItemView>
#include <QAction>
#include <QApplication>
#include <QAbstractSpinBox>
#include <QLineEdit>
#include <QCloseEvent>
#include <QComboBox>
#include <QDialog>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QFileSystemWatcher>
#include <QGuiApplication>
#include <QKeyEvent>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <cstdio>
#include <QSettings>
#include <QSignalBlocker>
#include <QStandardItemModel>
#include <QScreen>
#include <QStatusBar>
#include <QTimer>
#include <OpenImageIO/imageio.h>
#include <algorithm>
#include <cmath>

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

namespace {

// The AOV box's data for a layer no AOV took: kLayerItem + its index in Session::otherLayers().
constexpr int kLayerItem = 1000;

QString errorText(const std::exception& e) { return QString::fromStdString(e.what()); }

// Whether `w` takes typed text.
bool takesText(const QWidget* w) {
  if (qobject_cast<const QLineEdit*>(w) || qobject_cast<const QAbstractSpinBox*>(w)) return true;
  const auto* combo = qobject_cast<const QComboBox*>(w);
  return combo && combo->isEditable();
}

// Whether a key without Ctrl or Alt is one a text field uses: text, Tab (to move on), editing and cursor keys.
bool fieldKey(const QKeyEvent* k) {
  if (k->modifiers() & (Qt::ControlModifier | Qt::AltModifier | Qt::MetaModifier)) return false;
  switch (k->key()) {
    case Qt::Key_Tab: case Qt::Key_Backtab: case Qt::Key_Backspace: case Qt::Key_Delete: case Qt::Key_Left:
    case Qt::Key_Right: case Qt::Key_Up: case Qt::Key_Down: case Qt::Key_Home: case Qt::Key_End:
      return true;
    default:
      return !k->text().isEmpty() && k->text().at(0).isPrint();
  }
}
}  // namespace

bool MainWindow::eventFilter(QObject* watched, QEvent* event) {
  if (event->type() == QEvent::ShortcutOverride) {
    const auto* w = qobject_cast<QWidget*>(watched);
    if (w && w->window() == this && takesText(w) && fieldKey(static_cast<QKeyEvent*>(event))) {
      event->accept();  // the key goes to the field, not to a shortcut
      return true;
    }
  }
  return QMainWindow::eventFilter(watched, event);
}

struct MainWindow::Rendered {
  std::vector<Pane> panes;
  QSize size;
  std::vector<Source> sources;  // what each pane is
};

void MainWindow::setCanvasPanes(std::vector<Pane> panes, QSize size, std::vector<Source> sources) {
  // One pane shown: the same image once B or the heatmap comes or goes, though its index moves.
  std::optional<Source> shown;
  if (const int i = canvas_->current(); canvas_->layout() == ImageCanvas::Layout::Single && i >= 0 &&
                                        i < static_cast<int>(canvas_sources_.size()))
    shown = canvas_sources_[static_cast<size_t>(i)];
  canvas_->setPanes(std::move(panes), size);
  canvas_sources_ = std::move(sources);
  if (!shown) return;
  for (size_t i = 0; i < canvas_sources_.size(); ++i)
    if (canvas_sources_[i] == *shown) canvas_->setCurrent(static_cast<int>(i));
}

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
  qApp->installEventFilter(this);  // ShortcutOverride reaches the focused field, not the window: see eventFilter
  display_ = DisplayTransform::load_default();
  canvas_ = new ImageCanvas(this);
  canvas_->setObjectName("canvas");
  setCentralWidget(canvas_);
  help_ = new HelpOverlay(canvas_);
  render_ = std::make_unique<LatestTask<Rendered>>(this, [this](Rendered&& r) { showRendered(std::move(r)); });

  buildDocks();
  buildToolBar();
  buildActions();
  buildFrameBar();
  help_->setShortcuts(shortcutRows());

  size_label_ = new QLabel(this);
  zoom_label_ = new QLabel(this);
  cursor_label_ = new QLabel(this);
  cursor_label_->setObjectName("cursorLabel");
  cursor_label_->setMinimumWidth(320);
  statusBar()->addPermanentWidget(cursor_label_);
  statusBar()->addPermanentWidget(size_label_);
  statusBar()->addPermanentWidget(zoom_label_);
  connect(statusBar(), &QStatusBar::messageChanged, this, [this](const QString& m) {
    if (!m.isEmpty()) return;
    status_text_.clear();
    statusBar()->setToolTip({});
  });
  say(tr("Colour: %1").arg(QString::fromStdString(display_->source())), 8000);
  if (!display_->note().empty()) say(QString::fromStdString(display_->note()), 15000);

  connect(session_, &Session::loadStarted, this, [this](const QString& what) {
    say(tr("Loading %1...").arg(what));
  });
  connect(session_, &Session::loaded, this, &MainWindow::onLoaded);
  connect(session_, &Session::aboutToSwitch, this, [this] {
    views_[session_->renderId(session_->currentRender())] =
        SavedView{canvas_->autoFit(), canvas_->zoom(), canvas_->center(), canvas_->roi()};
  });
  connect(session_, &Session::renderListChanged, this, &MainWindow::updateTitle);
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
    say(tr("Reference loaded"), 5000);
    // Open Recent opens the render with it next time.
    if (const auto& ref = session_->loadOptions().reference; ref && session_->liveName().isEmpty()) {
      QStringList inputs;
      for (const auto& p : session_->inputs()) inputs << QString::fromStdString(p.string());
      RecentRenders().setReference(inputs, QString::fromStdString(ref->string()));
      rebuildRecentMenu();
    }
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
    say(message, 15000);
    if (interactive_) QMessageBox::warning(this, tr("Add result"), message);
  });
  connect(session_, &Session::denoisedTileChanged, this, &MainWindow::patchDenoisedTile);
  connect(canvas_, &ImageCanvas::hovered, this, [this](std::optional<QPoint> p) {
    hover_ = p;
    const auto map = heatmap_->map();
    inspector_->inspect(*session_, p, map.get(), heatmap_->title());
    updateStatus();
    updateImageHistogram();
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
    const QStringList files = QFileDialog::getOpenFileNames(this, tr("Add results to compare"), startFolder(), kImageFilter);
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
    say(tr("Denoising with %1").arg(what));
  });
  connect(denoise_, &DenoisePanel::finished, this, [this](bool ok, const QString& message) {
    say(ok ? tr("Denoised: %1").arg(session_->denoisedDescription()) : message, 10000);
    updateTitle();
    refreshPanes();  // the pane labels say whether the result is complete
    refreshAnalysis();
  });
  rebuildRecentMenu();
  updateStatus();
}

MainWindow::~MainWindow() { render_.reset(); }  // first: its jobs post to this window

void MainWindow::showRendered(Rendered&& r) {
  setCanvasPanes(std::move(r.panes), r.size, std::move(r.sources));
  if (pending_view_) {  // a render switched to: the view it was left with
    if (pending_view_->fitted) canvas_->fit();
    else canvas_->setView(pending_view_->zoom, pending_view_->center);
    pending_view_.reset();
  }
  setWipePair(wipe_a_, wipe_b_);
  if (pending_pane_ && paneIndex(*pending_pane_) >= 0) {
    showPane(*pending_pane_);
    pending_pane_.reset();
  }
  // Tiles that landed while these panes were being drawn are in the session: show them too.
  if (const int d = paneIndex(Source::Denoised); d >= 0 && session_->denoised()) {
    canvas_->setPaneValues(d, session_->denoisedShared());
    if (denoise_->running())
      for (const Rect& t : run_tiles_) drawDenoisedTile(t);
  }
  applyHeatmap();
  updateStatus();
  updateImageHistogram();
  emit panesRendered();
}

// ---------------------------------------------------------------------------------------------------------------
// Construction

void MainWindow::openFiles(const QStringList& files, const LoadOptions& options, bool focus) {
  if (files.isEmpty()) return;
  std::vector<std::filesystem::path> inputs;
  for (const auto& f : files) inputs.emplace_back(f.toStdString());
  last_error_.clear();
  mapping_retry_ = false;
  load_from_renderer_ = false;
  session_->open(inputs, options, focus);
  addRecent(files, options.reference ? QString::fromStdString(options.reference->string()) : QString());
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
  if (!stack) {  // the last render was closed
    layer_ = -1;
    rebuildLayerItems();
    setRoi(std::nullopt);
    metrics_->compute({});
    heatmap_->computeMap(nullptr, QString(), tr("no render"));
    updateTitle();
    refreshPanes();
    updateStatus();
    watchInputs();
    return;
  }
  // Fall back to colour when the new render lacks the AOV being shown. A layer shown is looked for in it by name
  // (rebuildLayerItems): indices of the last render's layers mean nothing here.
  const QString layer_shown = wanted_layer_;
  layer_ = -1;
  if (!session_->hasAov(aov_)) setAov(AovRole::Color);
  const int roles = static_cast<int>(std::size(kViewableAovs));
  for (int i = 0; i < std::min(roles, aov_box_->count()); ++i) {
    auto* model = qobject_cast<QStandardItemModel*>(aov_box_->model());
    if (model) model->item(i)->setEnabled(session_->hasAov(static_cast<AovRole>(aov_box_->itemData(i).toInt())));
  }
  wanted_layer_ = layer_shown;
  rebuildLayerItems();
  QStringList notes;
  for (const auto& n : stack->notes) notes << QString::fromStdString(n);
  // Another open render shown again: its own region and view, as it was left.
  if (session_->switchedRender()) {
    const auto it = views_.find(session_->renderId(session_->currentRender()));
    pending_view_ = it != views_.end() ? it->second : SavedView{};
    setRoi(pending_view_->roi);
  } else if (const auto roi = canvas_->roi()) {
    // A region drawn on the last render is kept where it lies inside this one (a reload, another frame, another
    // render), clipped to it otherwise, and dropped when none of it is inside: it never reaches outside the image.
    const Rect& d = stack->data_window;
    const int64_t x0 = std::max<int64_t>(roi->x, 0), y0 = std::max<int64_t>(roi->y, 0);
    const int64_t x1 = std::min(roi->x + roi->width, d.width), y1 = std::min(roi->y + roi->height, d.height);
    const Rect inside{x0, y0, x1 - x0, y1 - y0};
    if (inside != *roi) {
      notes << (inside.empty() ? tr("the region x %1, y %2, %3 x %4 lies outside this render: cleared")
                                     .arg(roi->x).arg(roi->y).arg(roi->width).arg(roi->height)
                               : tr("the region is clipped to this render: x %1, y %2, %3 x %4")
                                     .arg(inside.x).arg(inside.y).arg(inside.width).arg(inside.height));
      setRoi(inside.empty() ? std::nullopt : std::optional<Rect>(inside));
    }
  }
  say(tr("Loaded %1 (%2)%3")
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
  // Channels that no convention recognises: the user can assign them (once per channel layout), so the status bar
  // says what is asked, not that the load failed.
  const bool mapping_problem = kind == static_cast<int>(ErrorKind::Mapping) ||
                               (kind == static_cast<int>(ErrorKind::Input) && message.contains("channel"));
  const bool can_map = mapping_problem && inputs.size() == 1 && QFileInfo(inputs.front()).isFile();
  say(can_map && interactive_ && !load_from_renderer_ && !auto_reloading_
          ? tr("Assign the channels of %1: %2").arg(QFileInfo(inputs.front()).fileName(), message)
          : tr("Could not load: %1").arg(message),
      15000);
  if (load_from_renderer_) {
    std::fprintf(stderr, "residue: a renderer's open request failed: %s\n", qPrintable(message));
    return;
  }
  if (auto_reloading_) {  // a file caught half-written: the next change reloads it again
    auto_reloading_ = false;
    watchInputs();
    return;
  }
  if (can_map) {
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
    if (probe.exec() != QDialog::Accepted) return say(tr("Not loaded: the channels of %1 were not assigned")
                                                          .arg(QFileInfo(inputs.front()).fileName()), 15000);
    {
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

void MainWindow::addRecent(const QStringList& files, const QString& reference) {
  RecentRenders().add(files, reference);
  rebuildRecentMenu();
}

void MainWindow::rebuildRecentMenu() {
  recent_menu_->clear();
  const std::vector<RecentRender> recent = RecentRenders().list();
  for (const RecentRender& r : recent) {
    auto* a = recent_menu_->addAction(r.label());
    a->setToolTip(r.inputs.join('\n') + (r.reference.isEmpty() ? QString() : tr("\nreference: %1").arg(r.reference)));
    connect(a, &QAction::triggered, this, [this, r] {
      LoadOptions o;
      if (!r.reference.isEmpty()) {
        if (QFileInfo::exists(r.reference)) o.reference = r.reference.toStdString();
        else say(tr("The reference %1 is gone: opened without it").arg(r.reference), 10000);
      }
      openFiles(r.inputs, o);
    });
  }
  recent_menu_->setEnabled(!recent.empty());
}

// ---------------------------------------------------------------------------------------------------------------
// View

DisplaySettings MainWindow::displaySettings() const {
  DisplaySettings s;
  s.exposure = exposure_box_->value();
  s.offset = offset_box_->value();
  s.channel = channel();
  s.gamma = gamma_box_->value();
  s.clipping = clipping_ && clipping_->isChecked();
  s.false_colour = false_colour_ && false_colour_->isChecked();
  s.display = display_box_->currentText().toStdString();
  s.view = view_box_->currentText().toStdString();
  return s;
}

void MainWindow::setExposure(double stops) { exposure_box_->setValue(stops); }
void MainWindow::setChannel(DisplayChannel c) { channel_box_->setCurrentIndex(channel_box_->findData(static_cast<int>(c))); }
void MainWindow::setClippingWarning(bool on) {
  clipping_->setChecked(on);
  refreshPanes();
}

void MainWindow::setFalseColour(bool on) {
  false_colour_->setChecked(on);
  refreshPanes();
}

DisplayChannel MainWindow::channel() const { return static_cast<DisplayChannel>(channel_box_->currentData().toInt()); }
double MainWindow::exposure() const { return exposure_box_->value(); }

void MainWindow::setAov(AovRole aov) {
  wanted_layer_.clear();
  if (aov_ == aov && layer_ < 0 && aov_box_->currentData().toInt() == static_cast<int>(aov)) return;
  aov_ = aov;
  layer_ = -1;
  const QSignalBlocker block(aov_box_);
  aov_box_->setCurrentIndex(aov_box_->findData(static_cast<int>(aov)));
  refreshPanes();
}

bool MainWindow::setLayer(const QString& name) {
  if (!session_->hasStack()) {
    wanted_layer_ = name;
    return true;
  }
  const auto& layers = session_->otherLayers();
  for (size_t i = 0; i < layers.size(); ++i)
    if (QString::fromStdString(layers[i].name) == name) {
      showBoxItem(aov_box_->findData(kLayerItem + static_cast<int>(i)));
      return layer_ == static_cast<int>(i);
    }
  say(tr("%1 has no layer \"%2\" other than its AOVs").arg(session_->title(), name), 5000);
  return false;
}

QString MainWindow::layer() const {
  const auto& layers = session_->otherLayers();
  return layer_ >= 0 && layer_ < static_cast<int>(layers.size())
             ? QString::fromStdString(layers[static_cast<size_t>(layer_)].name)
             : QString();
}

void MainWindow::showBoxItem(int index) {
  if (index < 0) return;
  const int item = aov_box_->itemData(index).toInt();
  if (item < kLayerItem) {
    setAov(static_cast<AovRole>(item));
    return;
  }
  const int picked = item - kLayerItem;
  if (!readLayer(picked)) {
    const QSignalBlocker block(aov_box_);
    aov_box_->setCurrentIndex(aov_box_->findData(layer_ >= 0 ? kLayerItem + layer_ : static_cast<int>(aov_)));
    return;
  }
  layer_ = picked;
  wanted_layer_ = layer();
  const QSignalBlocker block(aov_box_);
  aov_box_->setCurrentIndex(index);
  refreshPanes();
}

bool MainWindow::readLayer(int index) {
  try {
    session_->otherLayer(index);  // read now (then kept), so that a file that cannot be read is said here
    return true;
  } catch (const Error& e) {
    say(tr("Cannot show layer %1: %2")
            .arg(QString::fromStdString(session_->otherLayers()[static_cast<size_t>(index)].name),
                 QString::fromStdString(e.what())),
        8000);
    return false;
  }
}

void MainWindow::rebuildLayerItems() {
  const QSignalBlocker block(aov_box_);
  const int roles = static_cast<int>(std::size(kViewableAovs));  // the box's first entries; the layers follow
  while (aov_box_->count() > roles) aov_box_->removeItem(roles);
  const auto& layers = session_->otherLayers();
  if (!layers.empty()) aov_box_->insertSeparator(aov_box_->count());
  // Listed without the view-layer prefix they all share ("ViewLayer."), which only widens the box; the pane's
  // label and the tooltip give the whole name.
  QString shared_prefix;
  if (!layers.empty()) {
    const QString first = QString::fromStdString(layers.front().name);
    if (const auto dot = first.indexOf('.'); dot > 0) shared_prefix = first.left(dot + 1);
    for (const auto& l : layers)
      if (!QString::fromStdString(l.name).startsWith(shared_prefix)) shared_prefix.clear();
  }
  for (size_t i = 0; i < layers.size(); ++i) {
    const QString name = QString::fromStdString(layers[i].name);
    aov_box_->addItem(name.mid(shared_prefix.size()), kLayerItem + static_cast<int>(i));
    aov_box_->setItemData(aov_box_->count() - 1, name, Qt::ToolTipRole);
  }
  aov_box_->view()->setMinimumWidth(aov_box_->view()->sizeHintForColumn(0) + 16);
  // The layer shown on the last render (a shot's previous frame), or the one asked for, when this one has it.
  const QString wanted = wanted_layer_;
  layer_ = -1;
  aov_box_->setCurrentIndex(aov_box_->findData(static_cast<int>(aov_)));
  if (!wanted.isEmpty()) {
    const int index = aov_box_->findData(wanted, Qt::ToolTipRole);
    if (index >= 0 && aov_box_->itemData(index).toInt() >= kLayerItem) {
      const int found = aov_box_->itemData(index).toInt() - kLayerItem;
      if (readLayer(found)) {
        layer_ = found;
        aov_box_->setCurrentIndex(index);
      }
    }
  }
  wanted_layer_ = wanted;
}

void MainWindow::cycleAov(int step) {
  if (!session_->hasStack()) return;
  const int n = aov_box_->count();
  auto* model = qobject_cast<QStandardItemModel*>(aov_box_->model());
  int i = aov_box_->currentIndex();
  for (int k = 0; k < n; ++k) {
    i = (i + step + n) % n;
    const QStandardItem* item = model ? model->item(i) : nullptr;
    if (item && item->isEnabled() && item->isSelectable() && !aov_box_->itemText(i).isEmpty()) break;
  }
  showBoxItem(i);
  say(tr("AOV: %1").arg(layer_ >= 0 ? layer() : display_name(aov_)), 3000);
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
  say(canvas_->panes()[static_cast<size_t>(canvas_->current())].label, 3000);
}

void MainWindow::pickResult(int index, bool as_b) {
  // The rows as the Results tab shows them (sorted as the user sorted them), numbered in its # column.
  const std::vector<int> ids = metrics_->visibleIds();
  if (index < 0 || index >= static_cast<int>(ids.size())) {
    say(tr("There is no result %1 (the Results tab lists them)").arg(index + 1), 4000);
    return;
  }
  const int id = ids[static_cast<size_t>(index)];
  if (as_b) session_->setB(id);
  else session_->setA(id);
  say(tr("%1: %2").arg(as_b ? "B" : "A", session_->resultName(id)), 4000);
}

void MainWindow::stepRender(int step) {
  const int n = session_->renderCount();
  if (n < 2) return;
  const int i = (session_->currentRender() + step + n) % n;
  session_->showRender(i);
  say(tr("Render %1 of %2: %3").arg(i + 1).arg(n).arg(session_->title()), 4000);
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
    setCanvasPanes({}, {}, {});
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
  if (layer_ >= 0) {
    try {
      in.layer = session_->otherLayer(layer_);  // read already, when it was picked
      in.layer_name = layer();
    } catch (const Error&) {
    }
  }
  // During a run from the noisy colour the unfinished tiles *are* the noisy colour: draw from the stack (which
  // never changes) rather than holding the image the tiles are written into (that would copy it per tile).
  const bool a_running = denoise_->controller()->runningResult() == session_->a() && session_->a() >= 0;
  in.denoised = a_running && denoise_->runningFromNoisy() ? shared(Source::Noisy) : session_->denoisedShared();
  in.compare = session_->compareShared();
  in.reference = shared(Source::Reference);
  in.heat_image = heatmap_->image();
  in.heat_map = heatmap_->map();
  in.heat_title = heatmap_->title();
  in.heat_placeholder = heatmap_->placeholder();
  const auto label = [this](int id) {
    const Result* r = session_->result(id);
    if (!r) return QString();
    QString text = session_->resultName(id);
    if (!r->done()) text += " (" + r->stateText + ")";
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
      auto preview = std::make_shared<Rendered>(Rendered{render_panes(in, step), size, in.sources});
      QMetaObject::invokeMethod(this, [this, preview, generation = token.generation()] {
        if (render_->pending(generation))
          setCanvasPanes(std::move(preview->panes), preview->size, std::move(preview->sources));
        applyHeatmap();
        emit panesRendered();
      }, Qt::QueuedConnection);
    }
    return Rendered{render_panes(in, 1), size, in.sources};
  });
}

void MainWindow::patchDenoisedTile(const Rect& rect) {
  if (denoise_->running()) run_tiles_.push_back(rect);
  drawDenoisedTile(rect);
}

void MainWindow::drawDenoisedTile(const Rect& rect) {
  const int i = paneIndex(Source::Denoised);
  // Shared, not borrowed: the canvas may paint these values after the session has let the result go (a new
  // image adopted), until its next panes arrive.
  const std::shared_ptr<const Image> d = session_->denoisedShared();
  if (i < 0 || !d) return;
  try {
    canvas_->patchPane(i, QPoint(static_cast<int>(rect.x), static_cast<int>(rect.y)),
                       display_->render(*d, 0, 3, rect, displaySettings(), Encoding::SceneLinear));
    canvas_->setPaneValues(i, d);
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
  // Frames of a sequence: each result against itself on frame t-1 (the temporal column and map).
  if (session_->sequence()) {
    in.frame = stack;
    in.previous_frame = session_->frameStack(session_->frame() - 1);
    in.rows.front().previous = session_->previousImage(nullptr);
  }
  for (const auto& r : session_->results()) {
    MetricsPanel::Row row;
    row.id = r.id;
    row.name = session_->resultName(r.id);
    row.file = r.file;
    row.description = r.description;
    // A result still being made is listed without scores: its pixels are half noisy.
    const bool made_now = r.id == running || (r.atStrength() && r.base == running);
    if (!made_now) row.image = r.image;
    if (in.frame && !made_now) row.previous = session_->previousImage(&r);
    row.seconds = r.seconds;
    // A run that did not finish is half noisy input: listed with its state, never scored as if it were a result.
    row.state = r.state == RunState::Running ? tr("running") : r.state == RunState::Cancelled ? tr("cancelled")
              : r.state == RunState::Failed  ? tr("failed") : QString();
    row.state_text = r.done() ? QString() : r.stateText;
    if (r.state == RunState::Cancelled || r.state == RunState::Failed) row.image.reset();
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
  if (heatmap_->temporal()) return computeTemporalMap();
  // Against the reference, the FLIP map the Results tab already has serves the heatmap too (it is the slow one).
  const auto against_reference = [&](const std::shared_ptr<const Image>& test, const QString& subject,
                                     const QString& missing) {
    if (const auto map = heatmap_->flip() && test && in.reference ? metrics_->flipMap(test.get()) : nullptr)
      return heatmap_->computeMap([map] { return *map; }, subject, missing);
    heatmap_->compute(test, in.reference, subject, missing, metrics_->options());
  };
  switch (heatmap_->of()) {
    case HeatmapPanel::Of::A:
      against_reference(a_image, a_name.isEmpty() ? tr("A") : a_name,
                        !in.reference ? tr("no reference") : tr("no result A yet (denoise, or add a result)"));
      break;
    case HeatmapPanel::Of::B:
      against_reference(b_image, b_name.isEmpty() ? tr("B") : b_name,
                        !in.reference ? tr("no reference") : tr("no result B (Ctrl+1-9 picks one)"));
      break;
    case HeatmapPanel::Of::Noisy:
      against_reference(in.rows.front().image, tr("the noisy input"), tr("no reference"));
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
      canvas_->setPanePlaceholder(i, heatmap_->placeholder());
    }
  } else if (d == HeatmapPanel::Display::Overlay) {
    const int i = paneIndex(heatmap_->of() == HeatmapPanel::Of::Noisy ? Source::Noisy
                            : heatmap_->of() == HeatmapPanel::Of::B  ? Source::Compare
                                                                     : Source::Denoised);
    if (i >= 0 && !heatmap_->image().isNull()) canvas_->setOverlay(i, heatmap_->image());
  }
}

void MainWindow::say(const QString& text, int timeout_ms) {
  QStatusBar* bar = statusBar();
  int room = bar->width() - 24;  // the size grip and margins
  for (const QWidget* w : {static_cast<QWidget*>(cursor_label_), static_cast<QWidget*>(size_label_),
                           static_cast<QWidget*>(zoom_label_)})
    if (w && w->isVisible()) room -= w->width() + 8;
  const QString shown = bar->fontMetrics().elidedText(text, Qt::ElideMiddle, std::max(room, 120));
  status_text_ = text;
  bar->setToolTip(shown == text ? QString() : text);
  bar->showMessage(shown, timeout_ms);
}

void MainWindow::updateImageHistogram() {
  // The pane under the cursor, else A, else the noisy input: its luminance (Rec. 709 Y; a one-channel pane's
  // values), counted once per image.
  const auto& panes = canvas_->panes();
  const Pane* pane = nullptr;
  if (const auto i = canvas_->hoveredPane(); i && *i < static_cast<int>(panes.size())) pane = &panes[static_cast<size_t>(*i)];
  for (Source fallback : {Source::Denoised, Source::Noisy})
    for (size_t i = 0; i < canvas_sources_.size() && i < panes.size() && (!pane || !pane->values); ++i)
      if (canvas_sources_[i] == fallback) pane = &panes[i];
  if (!pane || !pane->values) {
    histogram_of_.reset();
    image_histogram_->setValues(nullptr, true, {1e-4, 1}, Colormap::Viridis, tr("no image"));
    return;
  }
  if (pane->values == histogram_of_.lock()) return;
  histogram_of_ = pane->values;
  const Image& v = *pane->values;
  const int first = pane->first_channel, count = std::min(pane->channel_count, v.channels() - first);
  auto y = std::make_shared<Image>(v.width(), v.height(), 1);
  for (int64_t row = 0; row < v.height(); ++row)
    for (int64_t x = 0; x < v.width(); ++x)
      y->at(x, row, 0) = count >= 3 ? rec709_luminance(v.at(x, row, first), v.at(x, row, first + 1), v.at(x, row, first + 2))
                                    : v.at(x, row, first);
  ColorScale log;
  log.log = true;
  const auto range = resolve_range(*y, log);
  image_histogram_->setValues(y, true, range, Colormap::Viridis,
                              tr("Luminance of %1 (log)").arg(pane->label.isEmpty() ? tr("the image") : pane->label));
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

QString MainWindow::listenForRenderers(quint16 port, size_t max_bytes) {
  if (!tev_) {
    tev_ = new TevServer(this, max_bytes > 0 ? max_bytes : TevServer::default_memory());
    live_timer_ = new QTimer(this);
    live_timer_->setSingleShot(true);
    live_timer_->setInterval(150);  // a renderer sends many tiles a second; show them a few times a second
    live_quiet_ = new QTimer(this);
    live_quiet_->setSingleShot(true);
    live_quiet_->setInterval(1000);
    connect(tev_, &TevServer::liveImageChanged, this, [this](const QString& name, bool focus) {
      // A stream takes the canvas when it asks (tev's grab_focus: on creating an image, usually), never by
      // merely updating: the render you switched to stays shown.
      if (name != live_pending_) live_focus_ = false;
      live_focus_ = live_focus_ || focus;
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
                            live_pending_, live_focus_);
        live_focus_ = false;
      } catch (const std::exception& e) {
        say(errorText(e), 10000);
      }
    });
    connect(tev_, &TevServer::openRequested, this, [this](const QString& path, const QString& channels, bool focus) {
      if (!channels.isEmpty())
        say(tr("Opening %1 (channel selector \"%2\" ignored: AOVs are recognised by name)")
                                     .arg(path, channels), 10000);
      openFiles({path}, {}, focus);
      load_from_renderer_ = true;  // a failure goes to the status bar: a client's requests never stack dialogs
    });
    connect(tev_, &TevServer::reloadRequested, this, [this] { session_->reload(); });
    connect(tev_, &TevServer::closeRequested, session_, &Session::closeLive);
    connect(tev_, &TevServer::protocolError, this, [this](const QString& message) {
      say(message, 15000);
    });
  }
  if (tev_->listening()) return {};
  return tev_->listen(port) ? QString() : tev_->errorString();
}

void MainWindow::updateTitle() {
  QString t = session_->hasStack() ? session_->title() + " - Residue" : QStringLiteral("Residue");
  if (session_->renderCount() > 1) t += tr(" (%1 of %2)").arg(session_->currentRender() + 1).arg(session_->renderCount());
  setWindowTitle(t);
}

void MainWindow::keyPressEvent(QKeyEvent* e) {
  if (e->key() == Qt::Key_Escape) {
    if (help_->isVisible()) help_->hide();
    else if (playing_) setPlaying(false);
    else denoise_->cancel();
    return;
  }
  QMainWindow::keyPressEvent(e);
}

void MainWindow::closeEvent(QCloseEvent* e) {
  denoise_->cancel();
  saveSettings();
  QMainWindow::closeEvent(e);
}

QStringList MainWindow::sideTabNames() { return {"results", "denoise", "heatmap", "pixel", "renders"}; }

std::optional<MainWindow::SideTab> MainWindow::sideTabFromName(const QString& name) {
  const qsizetype i = sideTabNames().indexOf(name.toLower());
  if (i < 0) return std::nullopt;
  return static_cast<SideTab>(i);
}

void MainWindow::showSideTab(SideTab tab) {
  QWidget* pages[] = {metrics_, denoise_, heatmap_, pixel_page_, render_list_};
  tabs_->setCurrentWidget(pages[static_cast<int>(tab)]);
}

}  // namespace residue::ui
