// DenoiseController: runs a denoise for the viewer without being a widget. A request (model, precision,
// backend, tile, post-steps, region) either names a result the session already keeps (shown again at no
// cost) or starts core's DenoiseJob, whose tiles go into a result of the session's list as they finish. It
// keeps the seconds per megapixel each model took here, picks the interactive tile size when asked for
// "auto", and reports progress and the end. The DenoisePanel is its face; tests drive it directly.
#pragma once

#include <QElapsedTimer>
#include <QObject>
#include <functional>
#include <map>
#include <memory>
#include <optional>

#include "core/denoise/denoise_job.h"
#include "core/nn/model_registry.h"
#include "core/nn/model_card.h"
#include "ui/result.h"

class QTimer;

namespace residue::ui {

class Session;

class DenoiseController : public QObject {
  Q_OBJECT
 public:
  struct Request {
    QString model;  // a model card's family: "small", "bilateral", "oidn", ...
    nn::Precision precision = nn::Precision::FP32;
    QString backend;  // empty: the fastest
    int64_t tile = 0;  // 0: tiles of about half a second at the model's speed (interactive_tile)
    bool energy_correction = true;
    bool variance_blend = true;
    int ensemble = 0;  // the self-ensemble's members (1, 2, 4, 8); 0: the model's own
    std::optional<Rect> roi;  // denoise only this region
  };
  struct Progress {
    int64_t done = 0, total = 0;  // tiles of the pass running
    double fraction = 0;          // of the work of every pass (a prefilter's included)
    bool preliminary = false;     // the tiles are a prefilter's or a prior's, before the result's
    double elapsed = 0, left = -1;  // seconds; left < 0: not known yet
  };

  DenoiseController(Session* session, std::vector<nn::ModelCard> models, QObject* parent = nullptr);
  ~DenoiseController() override;

  // The settings as a key: two requests with the same key make the same image.
  static QString key(const Request& r);
  // The short name a run's result gets: "small fp32", "oidn bf16 raw", "small fp32 x8".
  static QString name(const Request& r);
  // Starts `r`, or shows the result kept for it. When the model has no variant for the render's AOVs, the
  // cheapest model that has one runs instead (and its description says so). Returns false when nothing started
  // (one is running, no render is open, no model fits); finished() tells the outcome either way.
  bool start(const Request& r);
  void cancel();  // the job stops within one network layer (a filter: one tile); its finished tiles stay
  bool running() const { return job_ != nullptr; }
  int runningResult() const { return running() ? result_id_ : -1; }
  // True while a run that started from the noisy colour is in flight: its unfinished tiles are the noisy colour.
  bool runningFromNoisy() const { return running() && from_noisy_; }
  Progress progress() const;
  QString runningDescription() const { return description_; }
  // Seconds per megapixel for `model` at `precision`: as measured here when it ran, else its benchmark, else
  // an estimate from its FLOPs.
  double expectedSecondsPerMp(const QString& model, nn::Precision precision) const;
  std::optional<double> measuredSecondsPerMp(const QString& model) const;
  const std::vector<nn::ModelCard>& models() const { return models_; }
  // Called on the worker thread after each tile of the result, before it is handed to the GUI thread (the next
  // tile waits for it): lets a test hold a run at a tile, cancel it there and let it go, instead of racing it.
  void setTileGate(std::function<void()> gate) { tile_gate_ = std::move(gate); }

 signals:
  void started(QString description);
  void progressed(int64_t done, int64_t total);
  // ok: the result is complete (or covers the region asked for) and is A; otherwise `message` says why not.
  void finished(bool ok, QString message);

 private:
  bool start(const Request& r, const QString& asked);  // `asked`: the model the user picked
  void poll();
  void finish(bool ok, const QString& message = {}, RunState state = RunState::Done, const QString& state_text = {});

  Session* session_;
  std::vector<nn::ModelCard> models_;
  nn::ModelRegistry loaded_;
  std::function<void()> tile_gate_;
  std::map<QString, double> measured_s_per_mp_;  // also kept in the settings, per CPU (speedGroup())
  static QString speedGroup();
  Request request_;
  QString description_;
  int result_id_ = -1;
  bool from_noisy_ = false;
  QElapsedTimer clock_;
  QTimer* poll_ = nullptr;
  std::unique_ptr<DenoiseJob> job_;
};

}  // namespace residue::ui
