// MetricsPanel: the result list with its scores. One row per result (the noisy input first, then every denoise
// run and added file), with relMSE, SSIM and PSNR against the reference for the whole image and, when a region
// is dragged, for the region; HDR-FLIP (core/metrics/flip.h: whole image and region, from one map per result,
// computed after the other scores because it is the slow one); the run time; which result is A and which is B.
// Sortable by any column. Scores come from core's metrics on a worker thread (the numbers residue-cli prints) and
// are kept per image, so a new result or region only computes what is new. On a frame of a sequence with motion vectors, a temporal column
// scores how each result's error changed since frame t-1, along the motion (core/temporal/warped_error.h).
// Picking rows asks the owner to show them (the session decides).
#pragma once

#include <QWidget>
#include <map>
#include <memory>
#include <optional>

#include "core/aov/aov_stack.h"
#include "core/io/metrics_report.h"
#include "ui/latest_task.h"

class QComboBox;
class QDoubleSpinBox;
class QLabel;
class QPushButton;
class QTableWidget;

namespace residue::ui {

class MetricsPanel : public QWidget {
  Q_OBJECT
 public:
  explicit MetricsPanel(QWidget* parent = nullptr);
  ~MetricsPanel() override;

  struct Row {
    int id = -1;  // the result's id; -1 for the noisy input
    QString name;
    QString file;         // the image's file: the render, an added file; empty for a run
    QString description;  // what made it, in full (the name's tooltip)
    std::shared_ptr<const Image> image;  // null while it is being made: the row shows its state
    std::shared_ptr<const Image> previous;  // the same result on frame t-1 (sequences), for the temporal column
    double seconds = 0;
    QString state;        // empty when done; else a word shown with the name ("cancelled")
    QString state_text;   // the state in full, for the tooltip
    bool a = false, b = false;
  };
  struct Inputs {
    std::vector<Row> rows;
    std::shared_ptr<const Image> reference;
    QString reference_file;
    std::optional<Rect> roi;
    // Frames t and t-1 (with references and t's motion) when the render is a frame of a sequence: the temporal
    // column is shown.
    std::shared_ptr<const AovStack> frame, previous_frame;
    int64_t noisy_nan = 0, noisy_inf = 0, reference_nan = 0, reference_inf = 0;  // whole-image value counts
  };
  // Recomputes what is not known yet on a worker thread (a computation in flight is superseded); computed()
  // follows. The table lists the rows at once.
  void compute(Inputs inputs);
  metrics::Options options() const;  // eps and SSIM space as set in the panel, without the ROI
  // The last finished computation, as residue-cli writes it (for export): scoped to the ROI when there is one.
  // Empty rows when none.
  const io::MetricsReport& report() const { return report_; }
  const io::MetricsReport& wholeReport() const { return whole_; }  // the whole image, always
  bool busy() const;
  // The results' ids in the order the table shows them (the noisy input left out): keys 1-9 pick these, and the
  // table's first column numbers them.
  std::vector<int> visibleIds() const;
  // The HDR-FLIP map of `image` against the current reference, once computed here; null before.
  std::shared_ptr<const Image> flipMap(const Image* image) const;

 signals:
  void optionsChanged();  // eps or SSIM space edited: the owner calls compute() again
  void computed();
  void showAsA(int id);   // a row was picked as A (click, Enter) or B (the B button, Ctrl+click)
  void showAsB(int id);
  void removeRequested(int id);
  void addRequested();    // "Add..." : the owner asks for a file

 private:
  void showTable();
  void numberRows();  // the # column, after every sort
  int selectedId() const;

  QLabel* scope_ = nullptr;
  QTableWidget* table_ = nullptr;
  QLabel* counts_ = nullptr;
  QDoubleSpinBox* eps_ = nullptr;
  QComboBox* space_ = nullptr;
  QPushButton* set_b_ = nullptr;
  QPushButton* remove_ = nullptr;

  struct Key {  // one image's scores for one region
    const Image* image;
    int64_t x, y, w, h;
    bool operator<(const Key& o) const {
      return std::tie(image, x, y, w, h) < std::tie(o.image, o.x, o.y, o.w, o.h);
    }
  };
  struct Known {
    std::shared_ptr<const Image> image;  // keeps the key's pointer from being reused while it is here
    metrics::Scores scores;
  };
  std::map<Key, Known> known_;
  struct Pair {  // one result's images on frames t and t-1: its temporal error
    const Image* image;
    const Image* previous;
    bool operator<(const Pair& o) const { return std::tie(image, previous) < std::tie(o.image, o.previous); }
  };
  struct KnownTemporal {
    std::shared_ptr<const Image> image, previous;  // keep the key's pointers from being reused
    double value;
  };
  std::map<Pair, KnownTemporal> temporal_;
  struct KnownFlip {  // one image's HDR-FLIP against the reference
    std::shared_ptr<const Image> image;  // keeps the key's pointer from being reused
    std::shared_ptr<const Image> map;
    double mean;
    metrics::FlipExposures exposures;
  };
  std::map<const Image*, KnownFlip> flips_;
  std::vector<const Image*> flips_pending_;  // what the FLIP job in flight computes
  struct FlipComputed {
    std::map<const Image*, KnownFlip> flips;
  };
  std::unique_ptr<LatestTask<FlipComputed>> flip_task_;
  void computeFlip();
  const Image* known_reference_ = nullptr;
  metrics::Options known_options_;
  struct Computed {
    std::map<Key, Known> scores;
    std::map<Pair, KnownTemporal> temporal;
    QString error;  // e.g. a reference of another size: shown instead of scores
  };
  std::unique_ptr<LatestTask<Computed>> task_;
  QString error_;
  Inputs last_;
  io::MetricsReport report_, whole_;
  bool updating_ = false;  // the table is being refilled: selection changes are not the user's
  bool numbering_ = false;  // numberRows() is setting the # column
};

}  // namespace residue::ui
