// DenoisePanel: the speed-versus-accuracy control (shipped models with their cost, validation relMSE/SSIM and
// measured seconds per megapixel), the run settings, Denoise and Cancel, and the progress of the run with its
// elapsed and remaining time. The run itself, and the results kept per setting, are the DenoiseController's
// (ui/denoise_controller.h): this widget only shows and asks.
#pragma once

#include <QWidget>
#include <optional>

#include "ui/denoise_controller.h"

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
  void setTile(int64_t tile);  // 0: automatic (tiles of about half a second)
  void setRoi(std::optional<Rect> roi) { roi_ = roi; }
  DenoiseController::Request request() const;  // what Denoise would run now

  DenoiseController* controller() const { return controller_; }
  bool running() const { return controller_->running(); }
  double progressFraction() const;  // of the running denoise's tiles, 0 when none
  bool runningFromNoisy() const { return controller_->runningFromNoisy(); }
  const std::vector<nn::ModelCard>& models() const { return controller_->models(); }

 public slots:
  void start();   // Denoise with the selected model (or show the result kept for these settings)
  void cancel();

 signals:
  void started(QString description);
  // ok: a complete result is in the session; otherwise `message` says why not (cancelled, error).
  void finished(bool ok, QString message);
  void progressed(int64_t done, int64_t total);

 private:
  void showProgress();
  void fillTable();

  Session* session_;
  DenoiseController* controller_ = nullptr;
  std::optional<Rect> roi_;

  QTableWidget* table_ = nullptr;
  QComboBox* precision_ = nullptr;
  QComboBox* backend_ = nullptr;
  QComboBox* tile_ = nullptr;
  QComboBox* ensemble_ = nullptr;
  QCheckBox* roi_only_ = nullptr;
  QCheckBox* energy_ = nullptr;
  QCheckBox* blend_ = nullptr;
  QSlider* strength_ = nullptr;
  QLabel* strength_label_ = nullptr;
  QPushButton* denoise_ = nullptr;
  QPushButton* cancel_ = nullptr;
  QProgressBar* progress_ = nullptr;
  QLabel* status_ = nullptr;
  QTimer* tick_ = nullptr;  // the elapsed and remaining time, while a run is in flight
};

}  // namespace residue::ui
