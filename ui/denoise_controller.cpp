#include "ui/denoise_controller.h"

#include <QCoreApplication>
#include <algorithm>
#include <QSettings>
#include <QTimer>

#include "core/denoise/denoiser.h"
#include "core/denoise/method_registry.h"
#include "core/denoise/provenance_of.h"
#include "core/features/features.h"
#include "core/nn/model_alias.h"
#include "core/nn/model_registry.h"
#include "core/temporal/frame_window.h"
#include "core/util/cpu_peak.h"
#include "core/util/error.h"
#include "ui/session.h"

namespace residue::ui {

namespace {
bool covered(const std::vector<Rect>& rects, const Rect& r) {
  for (const auto& c : rects)
    if (c.contains(r)) return true;
  return false;
}

QString precisionName(nn::Precision p) { return nn::to_string(p); }
}  // namespace

DenoiseController::DenoiseController(Session* session, std::vector<nn::ModelCard> models, QObject* parent)
    : QObject(parent), session_(session), models_(std::move(models)) {
  poll_ = new QTimer(this);
  poll_->setInterval(50);
  connect(poll_, &QTimer::timeout, this, &DenoiseController::poll);
  // A reload, another frame or a closed render drops the run's result: the run is stopped. Showing another open
  // render does not: the run goes on into its own render's list.
  connect(session_, &Session::loaded, this, [this] {
    if (!session_->switchedRender()) cancel();
  });
  connect(session_, &Session::renderListChanged, this, [this] {
    if (running() && !session_->holds(result_id_)) cancel();
  });
  // The speeds measured on this CPU in earlier sessions (a model's "here" column survives a restart; another CPU
  // starts afresh).
  QSettings settings;
  settings.beginGroup(speedGroup());
  for (const QString& k : settings.childKeys()) {
    bool ok = false;
    const double v = settings.value(k).toDouble(&ok);
    if (ok && v > 0) measured_s_per_mp_[QString(k).replace('|', '/')] = v;
  }
}

QString DenoiseController::speedGroup() {
  QString cpu = QString::fromStdString(cpu_description());
  for (QChar& c : cpu)
    if (!c.isLetterOrNumber()) c = '_';
  return "measuredSecondsPerMp/" + cpu;
}

DenoiseController::~DenoiseController() {
  if (job_) job_->cancel();
  job_.reset();
}

QString DenoiseController::key(const Request& r) {
  if (is_model_free_method(r.model.toStdString())) return r.model;  // a filter: no precision, no post-steps
  return QString("%1 %2 %3%4%5%6")
      .arg(r.model, precisionName(r.precision), r.backend, r.energy_correction ? "" : " raw",
           r.variance_blend ? "" : " noblend", r.ensemble > 0 ? QString(" x%1").arg(r.ensemble) : QString());
}

QString DenoiseController::name(const Request& r) {
  if (is_model_free_method(r.model.toStdString())) return r.model;
  QString n = QString("%1 %2").arg(r.model, precisionName(r.precision));
  if (!r.backend.isEmpty()) n += " " + r.backend;
  if (!r.energy_correction) n += " raw";
  if (!r.variance_blend) n += " noblend";
  if (r.ensemble > 0) n += QString(" x%1").arg(r.ensemble);
  return n;
}

bool DenoiseController::start(const Request& req) { return start(req, req.model); }

bool DenoiseController::start(const Request& req, const QString& asked) {
  if (running() || !session_->hasStack()) return false;
  if (req.model.isEmpty()) {
    emit finished(false, tr("Pick a model first."));
    return false;
  }
  const auto stack = session_->stack();
  const QString k = key(req);
  std::optional<Rect> rect = req.roi && !req.roi->empty() ? req.roi : std::nullopt;

  // Nothing to run when these settings already made what is asked for.
  const Result* kept = session_->findRun(k);
  if (kept && kept->done() && (kept->complete || (rect && covered(kept->rects, *rect)))) {
    session_->setA(kept->id);
    emit finished(true, tr("%1: kept from an earlier run").arg(kept->name));
    return false;
  }
  request_ = req;
  request_.roi = rect;

  std::shared_ptr<const Method> method;
  QString variant, substitute;
  try {
    if (is_model_free_method(req.model.toStdString())) {
      method = make_method(std::string_view(req.model.toStdString()));
    } else {
      // A family without a variant for this render's AOVs (a stream with colour only, say): the cheapest
      // family that has one runs instead, and its name says so.
      std::vector<std::string> families;
      for (const auto& m : models_) families.push_back(m.family);
      if (const auto other = nn::ModelRegistry::substitute(req.model.toStdString(), feature_set_for(*stack), families))
        substitute = QString::fromStdString(*other);
      const QString name = substitute.isEmpty() ? req.model : substitute;
      variant = QString::fromStdString(nn::find_model_for(name.toStdString(), feature_set_for(*stack)).stem().string());
      method = make_method(loaded_.load(name.toStdString(), feature_set_for(*stack)));
    }
  } catch (const std::exception& e) {
    emit finished(false, QString::fromStdString(e.what()));
    return false;
  }
  if (!substitute.isEmpty()) {
    Request instead = req;
    instead.model = substitute;
    return start(instead, asked);
  }

  // A temporal method reads the frames beside this one, warped to it (core/temporal/frame_window.h): the
  // session holds frames t-1 and t+1 of a sequence; a frame it lacks is read as not valid, and said.
  std::shared_ptr<const AovStack> run_stack = stack;
  QString neighbours;
  if (const int radius = method->frame_radius(); radius > 0) {
    auto with = std::make_shared<AovStack>(*stack);
    std::vector<int> missing;
    try {
      missing = attach_neighbours(*with, radius, [this](int d) { return session_->frameStack(session_->frame() + d).get(); });
    } catch (const std::exception& e) {
      emit finished(false, QString::fromStdString(e.what()));
      return false;
    }
    run_stack = std::move(with);
    if (!session_->sequence()) {
      neighbours = tr(", no neighbouring frames (not a sequence)");
    } else if (!missing.empty()) {
      QStringList offsets;
      for (int d : missing) offsets << QString("t%1%2").arg(d < 0 ? "-" : "+").arg(std::abs(d));
      neighbours = tr(", without frame %1").arg(offsets.join(", "));
    }
  }
  // Continue the result these settings started (a new region adds to it), else start one from the noisy
  // colour, so that tiles that have not run yet show the input.
  from_noisy_ = !kept;
  if (kept) {
    result_id_ = kept->id;
  } else {
    Result r;
    r.key = k;
    r.name = name(req);
    const Image& noisy = stack->color.image;
    auto img = std::make_shared<Image>(noisy.width(), noisy.height(), 3);
    for (int64_t y = 0; y < noisy.height(); ++y)
      for (int64_t x = 0; x < noisy.width(); ++x)
        for (int c = 0; c < 3; ++c) img->at(x, y, c) = noisy.at(x, y, std::min(c, noisy.channels() - 1));
    r.image = std::move(img);
    result_id_ = session_->addResult(std::move(r));
  }

  const nn::Model* net = method->model();
  if (!net) {
    description_ = QString::fromStdString(method->architecture());
  } else {
    description_ = QString("%1 (%2, %3)").arg(variant, QString::fromStdString(net->architecture()),
                                              precisionName(req.precision));
    const int members = req.ensemble > 0 ? req.ensemble : net->ensemble;
    if (members > 1) description_ += tr(", self-ensemble x%1").arg(members);
    if (!req.energy_correction) description_ += tr(", no energy correction");
    // The blend as it will run: OIDN's networks never use it, and a model with tau 0 keeps its whole output.
    DenoiseOptions blend;
    blend.variance_blend = req.variance_blend;
    if (stack->variance && net->method == nn::Method::Residue)
      description_ += method->variance_blend_tau(blend) > 0 ? tr(", variance blend") : tr(", no variance blend");
    if (asked != req.model) description_ += tr(", instead of %1, which has no variant for this render's AOVs").arg(asked);
    else if (variant != req.model) description_ += tr(" — picked for the AOVs this render has");
  }
  description_ += neighbours;
  const QString description = description_;
  session_->updateResult(result_id_, [&](Result& r) {
    r.description = description;
    r.state = RunState::Running;
    r.stateText = tr("running");
  });
  session_->setA(result_id_);
  clock_.start();
  emit started(description_);

  DenoiseOptions options;
  options.precision = req.precision;
  options.backend = req.backend.toStdString();
  options.roi = rect;
  options.tile = req.tile;
  options.ensemble = req.ensemble;
  // A tile runs the network once per member of the self-ensemble.
  if (options.tile <= 0 && net)
    options.tile = interactive_tile(net->graph, expectedSecondsPerMp(req.model, req.precision) *
                                                    (req.ensemble > 0 ? req.ensemble : net->ensemble));
  options.energy_correction = req.energy_correction;
  options.variance_blend = req.variance_blend;
  // Tiles arrive on the worker thread and are handed to the GUI thread; poll() delivers the queued ones before
  // it ends a job, so none of an old job lands in a new one.
  const int id = result_id_;
  job_ = std::make_unique<DenoiseJob>(run_stack, method, options, [this, id, gate = tile_gate_](const Rect& r, const Image& pixels) {
    if (gate) gate();
    QMetaObject::invokeMethod(
        this, [this, id, r, pixels] { if (job_) session_->setResultTile(id, r, pixels); }, Qt::QueuedConnection);
  });
  poll_->start();
  return true;
}

DenoiseController::Progress DenoiseController::progress() const {
  Progress p;
  if (!running()) return p;
  p.elapsed = static_cast<double>(clock_.elapsed()) / 1000.0;
  if (!job_) return p;
  const auto jp = job_->progress();
  p.done = jp.done;
  p.total = jp.total;
  p.fraction = jp.fraction();
  p.preliminary = jp.preliminary;
  if (p.fraction > 0 && p.fraction < 1) p.left = p.elapsed / p.fraction * (1.0 - p.fraction);
  return p;
}

double DenoiseController::expectedSecondsPerMp(const QString& model, nn::Precision precision) const {
  if (const auto here = measured_s_per_mp_.find(key({model, precision})); here != measured_s_per_mp_.end())
    return here->second;
  for (const auto& m : models_) {
    if (m.family != model.toStdString()) continue;
    // Per member of the self-ensemble, as measured_s_per_mp_: a card's numbers are for all its members.
    const auto bench = m.seconds_per_mp(precision);
    if (bench) return *bench / m.ensemble;
    return m.gflop_per_mp / 50.0 / m.ensemble;  // no benchmark: 50 GFLOP/s, about what 2 cores of fp32 reach here
  }
  return 0.0;
}

std::optional<double> DenoiseController::measuredSecondsPerMp(const QString& model) const {
  for (const auto p : {nn::Precision::FP32, nn::Precision::BF16})
    if (const auto here = measured_s_per_mp_.find(key({model, p})); here != measured_s_per_mp_.end())
      return here->second;
  return std::nullopt;
}

void DenoiseController::cancel() {
  if (job_) job_->cancel();
}

void DenoiseController::poll() {
  if (!job_) return;
  const auto p = progress();
  if (p.total > 0) emit progressed(p.done, p.total);
  const auto st = job_->status();
  if (st == DenoiseJob::Status::Running) return;
  // Deliver the tiles still queued before the result is taken.
  QCoreApplication::sendPostedEvents(this);
  if (st == DenoiseJob::Status::Done) {
    const auto& stats = job_->stats();
    const Rect r = request_.roi.value_or(job_->result()->bounds());
    // The tiles shown so far are the network's output; the result may differ by the post-steps.
    session_->setResultTile(result_id_, r, crop(*job_->result(), r));
    const io::Provenance ran = provenance_of(job_->method(), stats);
    session_->updateResult(result_id_, [&](Result& res) { res.provenance = ran; });
    const double mp = static_cast<double>(r.area()) / 1e6;
    // Kept per network run: a self-ensemble's time divided by its members.
    if (mp > 0 && stats.seconds > 0) {
      const QString k = key({request_.model, request_.precision});
      measured_s_per_mp_[k] = stats.seconds / mp / std::max(1, stats.ensemble);
      QSettings settings;
      settings.setValue(speedGroup() + "/" + QString(k).replace('/', '|'), measured_s_per_mp_[k]);
    }
    finish(true, {});
  } else if (st == DenoiseJob::Status::Cancelled) {
    if (p.total == 0)  // stopped inside its first tile: nothing of it was finished
      finish(false, tr("cancelled before its first tile finished: the result is the noisy input"),
             RunState::Cancelled, tr("cancelled before its first tile"));
    else
      finish(false, tr("cancelled after %1 of %2 tiles: the rest is the noisy input").arg(p.done).arg(p.total),
             RunState::Cancelled, tr("cancelled after %1 of %2 tiles").arg(p.done).arg(p.total));
  } else {
    finish(false, QString::fromStdString(job_->error()), RunState::Failed, tr("failed"));
  }
}

void DenoiseController::finish(bool ok, const QString& message, RunState state, const QString& state_text) {
  poll_->stop();
  const double elapsed = static_cast<double>(clock_.elapsed()) / 1000.0;
  if (job_) job_->wait();
  job_.reset();
  const auto roi = request_.roi;
  session_->updateResult(result_id_, [&](Result& r) {
    r.state = state;
    r.stateText = state == RunState::Done ? QString() : state_text;
    if (!ok) return;
    r.seconds = elapsed;
    if (roi) r.rects.push_back(*roi);
    else r.complete = true;
  });
  emit finished(ok, message);
}

}  // namespace residue::ui
