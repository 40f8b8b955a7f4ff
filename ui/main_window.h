// MainWindow: the viewer. It wires the data flow of the product together:
//   Session (load AOVs, results A/B) -> DisplayTransform (exposure, OCIO) -> ImageCanvas (panes, zoom, ROI)
//                                    -> MetricsPanel (a row of scores per result) / HeatmapPanel (maps, histogram)
//                                    -> DenoisePanel -> DenoiseController (core DenoiseJob, tiles into a result)
//                                    -> export (core writers, atomic, never overwriting without asking)
// Every slow step runs on a worker thread; the UI thread only draws and routes.
#pragma once

#include <QFuture>
#include <QFutureWatcher>
#include <QElapsedTimer>
#include <QMainWindow>
#include <map>
#include <memory>
#include <optional>

#include "core/metrics/metrics.h"
#include "ui/canvas.h"
#include "ui/display_transform.h"
#include "ui/heatmap_panel.h"
#include "ui/session.h"
#include "ui/latest_task.h"

class QComboBox;
class QDoubleSpinBox;
class QLabel;
class QMenu;
class QTimer;
class QFileSystemWatcher;
class QAction;
class QTabWidget;

namespace residue::ui {

class DenoisePanel;
class MetricsPanel;
class PixelInspector;
class HelpOverlay;
class TevServer;

class MainWindow : public QMainWindow {
  Q_OBJECT
 public:
  explicit MainWindow(QWidget* parent = nullptr);
  ~MainWindow() override;

  Session* session() const { return session_; }
  ImageCanvas* canvas() const { return canvas_; }
  MetricsPanel* metricsPanel() const { return metrics_; }
  HeatmapPanel* heatmapPanel() const { return heatmap_; }
  DenoisePanel* denoisePanel() const { return denoise_; }
  PixelInspector* inspector() const { return inspector_; }
  class RenderList* renderList() const { return render_list_; }
  class Histogram* imageHistogram() const { return image_histogram_; }  // the Pixel tab's: the image's luminance
  QTabWidget* sideTabs() const { return tabs_; }
  // The side bar's tabs by what they are, whatever language their titles are in. Names: "results", "denoise",
  // "heatmap", "pixel", "renders" (--tab).
  enum class SideTab { Results, Denoise, Heatmap, Pixel, Renders };
  static QStringList sideTabNames();
  static std::optional<SideTab> sideTabFromName(const QString& name);
  void showSideTab(SideTab tab);

  // Settings kept across restarts (ui/main_window_settings.cpp): the window, layout, colour view, theme, model and
  // heatmap drawing. restoreSettings() sets them as the viewer last saved them and has them saved when the window closes;
  // a window that never calls it (tests, --screenshot) starts from the defaults and saves nothing.
  void restoreSettings();
  // The theme: the platform's palette, or Fusion in light or dark neutral greys (View > Theme, --theme).
  enum class Theme { System, Light, Dark };
  void setTheme(Theme theme);
  Theme theme() const { return theme_; }
  static QString themeName(Theme theme);  // "system", "light", "dark"
  static std::optional<Theme> themeFromName(const QString& name);

  // Opening. Errors go to a message box, or to the mapping dialog when the channels could not be mapped.
  // A render joins the image list (Session) and is shown; without `focus` (a client's grab_focus off) it joins
  // unshown.
  void openFiles(const QStringList& files, const LoadOptions& options = {}, bool focus = true);
  void openReferenceFile(const QString& file);
  // Adds images to compare with the render (another denoiser's output, ...) to the result list.
  void addResultFiles(const QStringList& files);
  // When false, load errors are not shown in dialogs (tests, screenshots); lastError() has them.
  void setInteractive(bool on) { interactive_ = on; }
  QString lastError() const { return last_error_; }
  // The status bar's message in full, while it is shown (the bar shows it elided in the middle when it is wider
  // than the bar, with the whole text as its tooltip); empty once it has timed out.
  QString statusText() const { return status_text_; }

  // Renderers streaming over tev's protocol (ui/tev_server.h): listens on the loopback interface. Returns an
  // error message (the port is taken, ...) or an empty string. A streamed image is shown as the render, once
  // its updates pause for a moment.
  QString listenForRenderers(quint16 port, size_t max_bytes = 0);
  TevServer* tevServer() const { return tev_; }

  // View state.
  void setExposure(double stops);
  double exposure() const;
  void setAov(AovRole aov);
  AovRole aov() const { return aov_; }
  // A layer no AOV took (Session::otherLayers), by name, shown for Noisy instead of the AOV; false (said) when the
  // render has none of that name. Asked before a render is open, it is looked for in the first one.
  bool setLayer(const QString& name);
  QString layer() const;  // the layer shown for Noisy; empty when an AOV is
  void setChannel(DisplayChannel channel);  // every pane's colour, or one channel alone
  void setClippingWarning(bool on);         // View > Clipping Warning
  void setFalseColour(bool on);             // View > False Colour
  DisplayChannel channel() const;
  void setRoi(std::optional<Rect> roi);  // as if dragged
  void showPane(Source s);               // single-pane layout on that image
  // The two panes a wipe, flip or A | B layout shows; a source that is not shown falls back (B -> reference
  // -> noisy).
  void setWipePair(Source a, Source b);
  void setLayout(ImageCanvas::Layout layout);
  // Sequences (ui/main_window_frames.cpp): the frame shown, stepping, playing, and denoising every frame in turn.
  bool goToFrame(int64_t frame);  // false when the render is no sequence or has no such frame
  void stepFrame(int step);       // previous / next, wrapping around while playing
  void setPlaying(bool play);
  bool playing() const { return playing_; }
  void denoiseEveryFrame();       // with the selected settings, from the first frame; Esc stops it
  bool denoisingEveryFrame() const { return every_frame_; }
  class FrameBar* frameBar() const { return frame_bar_; }
  int paneIndex(Source s) const;         // index in canvas()->panes(), -1 when not shown
  bool rendering() const;                // panes being re-rendered
  bool busy() const;                     // anything running on a worker (load, render, metrics, heatmap, denoise)

  // Exports; each writes atomically and never replaces a file unless `overwrite`. Return an error message or
  // an empty string. They run on a worker thread; the returned future ends when the file is written.
  QFuture<QString> exportDenoisedExr(const QString& path, bool overwrite, bool half = true,
                                     const QString& compression = "zip");
  // .png (colour-mapped, with its colour bar and range below) or .exr (values)
  QFuture<QString> exportHeatmap(const QString& path, bool overwrite);
  // A comparison sheet (ui/comparison_sheet.h): noisy, every result and the reference, labelled with their
  // scores, as PNG.
  QFuture<QString> exportComparison(const QString& path, bool overwrite);
  QFuture<QString> exportMetrics(const QString& path, bool overwrite);     // .json or .csv, every result
  // Everything at once into `folder` (ui/export_all.h): returns the error message, or an empty string. Files
  // that exist are replaced only when `overwrite`; else nothing is written and the message names them.
  // `region`: the region alone (ExportAllInputs::crop): each result's, the noisy input's and the reference's
  // pixels there, the maps cut to it, and its scores.
  QFuture<QString> exportAll(const QString& folder, bool overwrite, bool region = false);
  // What the canvas shows (the layout, wipe, zoom, labels) as a PNG of its size.
  QFuture<QString> exportView(const QString& path, bool overwrite);

 signals:
  void panesRendered();  // the canvas shows the current images

 protected:
  // Keys typed into a field (the eps box, the heatmap's range) are the field's: Tab moves on from it and digits,
  // arrows and Backspace edit it, instead of running the window's shortcuts (next pane, result 1-9, frames).
  bool eventFilter(QObject* watched, QEvent* event) override;
  void closeEvent(QCloseEvent*) override;
  void keyPressEvent(QKeyEvent*) override;

 private:
  std::vector<std::pair<QString, QString>> shortcutRows() const;  // the help overlay's (keys, what they do)
  std::vector<QWidget*> rememberedControls() const;
  void saveSettings() const;
  void buildActions();
  void buildDocks();
  void buildToolBar();
  void buildFrameBar();
  void updateFrameBar();
  void playNext();  // panes drawn while playing: the next frame when its time has come
  void computeTemporalMap();  // the heatmap's temporal error of A, B or the noisy input
  void onLoaded();
  void onLoadFailed(const QString& message, int kind, const QStringList& inputs);
  void refreshPanes();
  void refreshAnalysis();
  void applyHeatmap();
  void patchDenoisedTile(const Rect& rect);  // a tile arrived: remember it and draw it
  void drawDenoisedTile(const Rect& rect);
  struct Rendered;  // panes drawn on a worker
  void showRendered(Rendered&& r);  // the newest panes, on the canvas
  void setCanvasPanes(std::vector<Pane> panes, QSize size, std::vector<Source> sources);
  void updateStatus();
  void say(const QString& text, int timeout_ms = 0);  // a status bar message (see statusText)
  void updateTitle();
  void addRecent(const QStringList& files, const QString& reference);  // File > Open Recent (ui/recent_renders.h)
  void rebuildRecentMenu();
  void cycleAov(int step);
  void cyclePane(int step);
  void pickResult(int index, bool as_b);  // keys 1-9 / Ctrl+1-9
  void stepRender(int step);              // PgUp / PgDn through the open renders
  void exportAllDialog(bool region = false);
  static const QString kImageFilter;  // the Open dialogs' file types
  QString startFolder() const;        // where they start: the render's folder, else the last render's
  struct SheetInputs;
  SheetInputs sheetInputs() const;
  bool looksLikeResult(const QString& file) const;
  void runExport(const QString& what, QFuture<QString> future);
  QString askSavePath(const QString& title, const QString& filter, const QString& suffix);
  DisplaySettings displaySettings() const;
  std::shared_ptr<const Image> shared(Source s) const;

  Session* session_ = nullptr;
  TevServer* tev_ = nullptr;
  QTimer* live_timer_ = nullptr;  // coalesces a stream's updates into one refresh
  QTimer* live_quiet_ = nullptr;  // fires when a stream has paused: time to denoise it
  QAction* live_denoise_ = nullptr;   // File > Denoise streamed images when they pause
  QFileSystemWatcher* watcher_ = nullptr;  // the open render's files, for reloading when a renderer rewrites them
  QTimer* reload_timer_ = nullptr;         // a rewrite is several events: reload once they stop
  QAction* auto_reload_ = nullptr;         // File > Reload when the files change
  bool auto_reloading_ = false;            // a failed automatic reload goes to the status bar, not a dialog
  void watchInputs();
  QString live_pending_;          // the streamed image to show when it fires
  std::shared_ptr<const DisplayTransform> display_;
  ImageCanvas* canvas_ = nullptr;
  MetricsPanel* metrics_ = nullptr;
  HeatmapPanel* heatmap_ = nullptr;
  DenoisePanel* denoise_ = nullptr;
  PixelInspector* inspector_ = nullptr;
  class RenderList* render_list_ = nullptr;
  QWidget* pixel_page_ = nullptr;
  class Histogram* image_histogram_ = nullptr;
  std::weak_ptr<const Image> histogram_of_;  // the values the image histogram counts (recounted when they change)
  void updateImageHistogram();
  // Each open render's view, kept while another is shown (Session::renderId -> zoom, centre, region).
  struct SavedView {
    bool fitted = true;
    double zoom = 1;
    QPointF center;
    std::optional<Rect> roi;
  };
  std::map<int, SavedView> views_;
  std::optional<SavedView> pending_view_;  // set on the canvas once the render switched to has its panes
  bool live_focus_ = true;                 // the pending streamed image's grab_focus
  HelpOverlay* help_ = nullptr;
  QTabWidget* tabs_ = nullptr;

  QComboBox* layout_box_ = nullptr;
  QComboBox* aov_box_ = nullptr;
  QComboBox* channel_box_ = nullptr;
  QDoubleSpinBox* exposure_box_ = nullptr;
  QDoubleSpinBox* offset_box_ = nullptr;
  QDoubleSpinBox* gamma_box_ = nullptr;
  QAction* clipping_ = nullptr;      // View > Clipping Warning (C)
  QAction* false_colour_ = nullptr;  // View > False Colour (Shift+C)
  QComboBox* display_box_ = nullptr;
  QComboBox* view_box_ = nullptr;
  QLabel* size_label_ = nullptr;
  QLabel* zoom_label_ = nullptr;
  QLabel* cursor_label_ = nullptr;
  QMenu* recent_menu_ = nullptr;

  AovRole aov_ = AovRole::Color;
  int layer_ = -1;          // index in session_->otherLayers(); -1: the AOV aov_ is shown
  QString wanted_layer_;    // kept from render to render (a shot's frames, a layer asked for before the load)
  void rebuildLayerItems();  // the AOV box's entries for the shown render's other layers
  void showBoxItem(int index);
  bool readLayer(int index);  // Session::otherLayer read; false, said, when its file cannot be read
  std::vector<Source> pane_sources_;
  Source wipe_a_ = Source::Denoised, wipe_b_ = Source::Compare;
  std::optional<Source> pending_pane_;  // to show in single layout once the panes include it
  std::vector<Source> canvas_sources_;  // what the canvas's panes are (pane_sources_ may be newer)
  std::optional<QPoint> hover_;
  bool interactive_ = true;
  bool load_from_renderer_ = false;  // the load in flight was asked for over tev's protocol: no dialogs
  QString last_error_;
  QString status_text_;
  bool mapping_retry_ = false;

  std::unique_ptr<LatestTask<Rendered>> render_;  // the panes, drawn on a worker
  std::vector<Rect> run_tiles_;  // tiles of the running denoise, re-drawn over panes rendered meanwhile
  int exports_running_ = 0;

  FrameBar* frame_bar_ = nullptr;
  class QToolBar* frames_toolbar_ = nullptr;
  QTimer* play_timer_ = nullptr;  // the rest of a frame's time while playing
  QElapsedTimer frame_clock_;     // since the frame shown was asked for
  std::vector<qint64> shown_at_;  // when the last frames were shown while playing (ms of play_clock_), for the fps
  QElapsedTimer play_clock_;
  bool playing_ = false;
  bool every_frame_ = false;      // denoising every frame in turn
  bool remember_settings_ = false;
  Theme theme_ = Theme::System;
  std::vector<QAction*> theme_actions_;  // View > Theme
};

}  // namespace residue::ui
