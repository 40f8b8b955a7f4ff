// DenoisePanel: the speed-versus-accuracy control (shipped models with their cost, validation relMSE/SSIM and
// measured seconds per megapixel), a Denoise button that runs core's DenoiseJob on a worker thread and writes
// each finished tile into the session (so tiles appear as they finish), progress with elapsed and remaining
// time, and Cancel. Results are cached per model and precision, so switching back to a model, or asking for a
// region already denoised, costs nothing, and a new ROI only runs the ROI.
#pragma once

#include <QElapsedTimer>
#include <QFutureWatcher>
#include <QWidget>
#include <map>
#include <memory>
#include <optional>

#include "core/denoise/denoise_job.h"
#include "ui/model_catalog.h"

class QCheckBox;
class QComboBox;
class QLabel;
class QProgressBar;
class QPushButton;
class QSlider;
class QTableWidget;
class QTimer;

namespace residue::ui {

class Session;

class DenoisePanel : public QWidget {
  Q_OBJECT
 public:
  DenoisePanel(Session* session, QWidget* parent = nullptr);
  ~DenoisePanel() override;

  // Selection, for menus, tests and the command line.
  bool selectModel(const QString& name);
  QString selectedModel() const;
  void setPrecision(nn::Precision p);
  nn::Precision precision() const;
  // Seconds per megapixel the model is expected to take: measured here if it ran, else its benchmark.
  double expectedSecondsPerMp(const QString& model) const;
  void setRoiOnly(bool on);
  void setTile(int64_t tile);  // 0: automatic (the largest tile that fits the memory budget)
  void setRoi(std::optional<Rect> roi) { roi_ = roi; }

  bool running() const { return job_ != nullptr || bilateral_running_ || preparing_; }
  double progressFraction() const;  // of the running denoise's tiles, 0 when none
  // True while a run that started from the noisy colour is in flight: its unfinished tiles are the noisy colour.
  bool runningFromNoisy() const { return running() && from_noisy_; }
  const std::vector<ModelEntry>& models() const { return models_; }

 public slots:
  void start();   // Denoise with the selected model (or restore it from the cache)
  void cancel();

 signals:
  void started(QString description);
  // ok: a complete result is in the session; otherwise `message` says why not (cancelled, error).
  void finished(bool ok, QString message);
  void progressed(int64_t done, int64_t total);

 private:
  struct CacheEntry {
    std::shared_ptr<Image> image;  // shared with the session while shown (copy on write there)
    bool full = false;
    std::vector<Rect> rects;  // regions denoised when not full
    QString description;
  };
  QString cacheKey() const;
  void finish(bool ok, const QString& message);
  void poll();
  void fillTable();

  Session* session_;
  std::vector<ModelEntry> models_;
  std::map<QString, std::shared_ptr<const nn::Model>> loaded_;
  std::map<QString, CacheEntry> cache_;
  std::map<QString, double> measured_s_per_mp_;
  std::optional<Rect> roi_;
  std::optional<Rect> running_rect_;
  QString running_key_, running_description_;

  QTableWidget* table_ = nullptr;
  QComboBox* precision_ = nullptr;
  QComboBox* backend_ = nullptr;
  QComboBox* tile_ = nullptr;
  QCheckBox* roi_only_ = nullptr;
  QCheckBox* energy_ = nullptr;
  QCheckBox* blend_ = nullptr;
  QSlider* strength_ = nullptr;
  QLabel* strength_label_ = nullptr;
  QPushButton* denoise_ = nullptr;
  QPushButton* cancel_ = nullptr;
  QProgressBar* progress_ = nullptr;
  QLabel* status_ = nullptr;
  QTimer* poll_ = nullptr;
  QElapsedTimer clock_;

  std::unique_ptr<DenoiseJob> job_;
  bool bilateral_running_ = false;
  bool preparing_ = false;
  bool from_noisy_ = false;  // between Denoise and the job's start: the session's image is not a result yet
  QFutureWatcher<std::shared_ptr<Image>>* bilateral_ = nullptr;
};

}  // namespace residue::ui
