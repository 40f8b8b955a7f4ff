// MetricsPanel: SSIM, relMSE, PSNR and MSE of the noisy and the denoised colour against the reference, for the
// whole image or the ROI, computed by core's metrics on a worker thread (the same numbers residue-cli prints).
#pragma once

#include <QWidget>
#include <memory>
#include <optional>

#include "core/io/metrics_report.h"
#include "ui/latest_task.h"

class QComboBox;
class QDoubleSpinBox;
class QLabel;
class QTableWidget;

namespace residue::ui {

class MetricsPanel : public QWidget {
  Q_OBJECT
 public:
  explicit MetricsPanel(QWidget* parent = nullptr);
  ~MetricsPanel() override;

  struct Inputs {
    std::shared_ptr<const Image> noisy, denoised, reference;
    QString noisy_file, denoised_file, reference_file;
    std::optional<Rect> roi;
    int64_t noisy_nan = 0, noisy_inf = 0, reference_nan = 0, reference_inf = 0;  // whole-image value counts
  };
  // Recomputes on a worker thread (a computation in flight is superseded); computed() follows.
  void compute(Inputs inputs);
  metrics::Options options() const;  // eps and SSIM space as set in the panel, without the ROI
  // The last finished computation, as residue-cli writes it (for export). Empty rows when none.
  const io::MetricsReport& report() const { return report_; }
  bool busy() const;

 signals:
  void optionsChanged();  // eps or SSIM space edited: the owner calls compute() again
  void computed();

 private:
  void showReport();

  QLabel* scope_ = nullptr;
  QTableWidget* table_ = nullptr;
  QLabel* counts_ = nullptr;
  QDoubleSpinBox* eps_ = nullptr;
  QComboBox* space_ = nullptr;
  struct Computed {
    io::MetricsReport report;
    QString error;  // e.g. a reference of another size: shown instead of scores
  };
  std::unique_ptr<LatestTask<Computed>> task_;
  QString error_;
  Inputs last_;
  io::MetricsReport report_;
};

}  // namespace residue::ui
