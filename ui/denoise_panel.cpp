#include "ui/denoise_panel.h"

#include <QCheckBox>
#include <QCoreApplication>
#include <QComboBox>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QProgressBar>
#include <QPushButton>
#include <QSlider>
#include <QTableWidget>
#include <QTimer>
#include <QVBoxLayout>
#include <QtConcurrent/QtConcurrentRun>

#include "core/denoise/bilateral.h"
#include "core/features/features.h"
#include "core/nn/backend.h"
#include "ui/session.h"

namespace residue::ui {

namespace {
enum Column { kName, kSize, kCost, kFp32, kBf16, kHere, kRelMse, kSsim, kColumns };

QString opt(const std::optional<double>& v, int precision, const QString& suffix = {}) {
  return v ? QString::number(*v, 'g', precision) + suffix : QStringLiteral("-");
}

QString duration(double seconds) {
  if (seconds < 60) return QString::number(seconds, 'f', 1) + " s";
  return QString("%1 min %2 s").arg(static_cast<int>(seconds / 60)).arg(static_cast<int>(seconds) % 60);
}

bool covered(const std::vector<Rect>& rects, const Rect& r) {
  for (const auto& c : rects)
    if (c.contains(r)) return true;
  return false;
}
}  // namespace

DenoisePanel::DenoisePanel(Session* session, QWidget* parent) : QWidget(parent), session_(session) {
  auto* layout = new QVBoxLayout(this);
  table_ = new QTableWidget(0, kColumns, this);
  table_->setObjectName("modelTable");
  table_->setHorizontalHeaderLabels({tr("model"), tr("blocks/width"), tr("GFLOP/MP"), tr("s/MP fp32"),
                                     tr("s/MP bf16"), tr("s/MP here"), tr("val relMSE"), tr("val SSIM")});
  table_->setSelectionBehavior(QAbstractItemView::SelectRows);
  table_->setSelectionMode(QAbstractItemView::SingleSelection);
  table_->setEditTriggers(QAbstractItemView::NoEditTriggers);
  table_->verticalHeader()->hide();
  table_->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  table_->setToolTip(tr("Speed against accuracy: seconds per megapixel as benchmarked (model file) and as "
                        "measured on this machine; relMSE and SSIM on the validation scenes."));
  layout->addWidget(table_);
  // Every model in view: the point of the table is to compare them.
  table_->setMinimumHeight(table_->horizontalHeader()->sizeHint().height() + 5 * 26);

  auto* row = new QHBoxLayout;
  precision_ = new QComboBox(this);
  precision_->setObjectName("precision");
  precision_->addItem("fp32", static_cast<int>(nn::Precision::FP32));
  precision_->addItem("bf16", static_cast<int>(nn::Precision::BF16));
  precision_->setToolTip(tr("bf16 runs about twice as fast on CPUs with AVX512-BF16 or AMX, at a small cost in "
                            "accuracy"));
  row->addWidget(precision_);
  backend_ = new QComboBox(this);
  backend_->setObjectName("backend");
  backend_->addItem(tr("fastest backend"), QString());
  for (const auto& b : nn::available_backends()) backend_->addItem(QString::fromStdString(b), QString::fromStdString(b));
  row->addWidget(backend_);
  tile_ = new QComboBox(this);
  tile_->setObjectName("tile");
  tile_->addItem(tr("auto tile"), 0);
  for (int t : {64, 128, 256, 512, 1024}) tile_->addItem(tr("tile %1").arg(t), t);
  tile_->setToolTip(tr("Tile edge: smaller tiles show progress sooner and use less memory; each tile also "
                       "computes a halo of the receptive field, so small tiles cost more in total. Auto: tiles "
                       "of about half a second each at the model's speed, so that Cancel stops at once"));
  row->addWidget(tile_);
  roi_only_ = new QCheckBox(tr("ROI only"), this);
  roi_only_->setObjectName("roiOnly");
  roi_only_->setToolTip(tr("Denoise only the region of interest (Shift+drag or right-drag on the image)"));
  row->addWidget(roi_only_);
  energy_ = new QCheckBox(tr("Energy"), this);
  energy_->setObjectName("energyCorrection");
  energy_->setChecked(true);
  energy_->setToolTip(tr("Energy correction: rescale the network's output to the noisy input's local mean "
                         "(Gaussian, 16 px). Networks trained with L1 on log colour darken very noisy dark "
                         "regions by up to 8 %; this removes that bias (see docs/MODELS.md)"));
  row->addWidget(energy_);
  blend_ = new QCheckBox(tr("Blend"), this);
  blend_->setObjectName("varianceBlend");
  blend_->setChecked(true);
  blend_->setToolTip(tr("Variance blend (renders with a variance AOV): where the input is already clean (small "
                        "relative variance over 7x7 pixels), keep more of it than of the network's output"));
  row->addWidget(blend_);
  layout->addLayout(row);

  // Strength re-blends the kept result with the noisy colour at once (core/denoise/strength.h): no new run.
  auto* strength_row = new QHBoxLayout;
  strength_label_ = new QLabel(tr("Strength 100 %"), this);
  strength_label_->setObjectName("strengthLabel");
  strength_ = new QSlider(Qt::Horizontal, this);
  strength_->setObjectName("strength");
  strength_->setRange(0, 100);
  strength_->setValue(100);
  strength_->setToolTip(tr("Denoising strength: 100 % shows the denoised result, 0 % the noisy input, between a "
                           "linear blend of the two (which keeps the brightness). Metrics, heatmaps and exports "
                           "follow it."));
  strength_row->addWidget(strength_label_);
  strength_row->addWidget(strength_, 1);
  layout->addLayout(strength_row);
  connect(strength_, &QSlider::valueChanged, this, [this](int v) {
    strength_label_->setText(tr("Strength %1 %").arg(v));
    session_->setStrength(static_cast<float>(v) / 100.0f);
  });

  auto* buttons = new QHBoxLayout;
  denoise_ = new QPushButton(tr("Denoise"), this);
  denoise_->setObjectName("denoiseButton");
  denoise_->setToolTip(tr("Denoise with the selected model (Ctrl+D)"));
  cancel_ = new QPushButton(tr("Cancel"), this);
  cancel_->setObjectName("cancelButton");
  cancel_->setEnabled(false);
  buttons->addWidget(denoise_);
  buttons->addWidget(cancel_);
  layout->addLayout(buttons);
  progress_ = new QProgressBar(this);
  progress_->setObjectName("denoiseProgress");
  progress_->setRange(0, 1);
  progress_->setValue(0);
  layout->addWidget(progress_);
  status_ = new QLabel(this);
  status_->setObjectName("denoiseStatus");
  status_->setWordWrap(true);
  layout->addWidget(status_);
  layout->addStretch(1);

  connect(denoise_, &QPushButton::clicked, this, &DenoisePanel::start);
  connect(cancel_, &QPushButton::clicked, this, &DenoisePanel::cancel);
  poll_ = new QTimer(this);
  poll_->setInterval(50);
  connect(poll_, &QTimer::timeout, this, &DenoisePanel::poll);
  bilateral_ = new QFutureWatcher<std::shared_ptr<Image>>(this);
  connect(bilateral_, &QFutureWatcherBase::finished, this, [this] {
    bilateral_running_ = false;
    auto img = bilateral_->result();
    if (!img) return finish(false, tr("bilateral filter failed"));
    const Rect r = running_rect_.value_or(img->bounds());
    session_->setDenoisedTile(r, crop(*img, r));
    finish(true, {});
  });
  // A new render invalidates every cached result.
  connect(session_, &Session::loaded, this, [this] {
    cancel();
    cache_.clear();
  });

  QStringList problems;
  models_ = scan_models(&problems);
  fillTable();
  selectModel("small");
  if (!problems.isEmpty()) status_->setText(problems.join("\n"));
}

DenoisePanel::~DenoisePanel() {
  if (job_) job_->cancel();
  job_.reset();
  bilateral_->waitForFinished();
}

void DenoisePanel::fillTable() {
  table_->setRowCount(static_cast<int>(models_.size()));
  for (size_t i = 0; i < models_.size(); ++i) {
    const auto& m = models_[i];
    const int r = static_cast<int>(i);
    auto* name = new QTableWidgetItem(m.name);
    name->setToolTip(m.baseline() ? m.variants : tr("%1\nvariants: %2").arg(m.path, m.variants));
    table_->setItem(r, kName, name);
    table_->setItem(r, kSize, new QTableWidgetItem(m.baseline() ? QString("-") : m.architecture));
    table_->setItem(r, kCost, new QTableWidgetItem(m.baseline() ? QString("-") : QString::number(m.gflop_per_mp, 'f', 0)));
    auto* fp32 = new QTableWidgetItem(opt(m.s_per_mp_fp32, 3));
    auto* bf16 = new QTableWidgetItem(opt(m.s_per_mp_bf16, 3));
    if (!m.benchmark_machine.isEmpty()) {
      fp32->setToolTip(tr("benchmarked on %1").arg(m.benchmark_machine));
      bf16->setToolTip(fp32->toolTip());
    }
    table_->setItem(r, kFp32, fp32);
    table_->setItem(r, kBf16, bf16);
    const auto here = measured_s_per_mp_.find(m.name);
    table_->setItem(r, kHere, new QTableWidgetItem(here == measured_s_per_mp_.end() ? QString("-")
                                                                                      : QString::number(here->second, 'g', 3)));
    auto* rel = new QTableWidgetItem(opt(m.val_relmse, 3));
    if (m.noisy_relmse) rel->setToolTip(tr("noisy input: %1").arg(*m.noisy_relmse, 0, 'g', 3));
    table_->setItem(r, kRelMse, rel);
    table_->setItem(r, kSsim, new QTableWidgetItem(opt(m.val_ssim, 4)));
  }
}

bool DenoisePanel::selectModel(const QString& name) {
  for (int r = 0; r < table_->rowCount(); ++r) {
    if (table_->item(r, kName)->text() == name) {
      table_->selectRow(r);
      return true;
    }
  }
  return false;
}

QString DenoisePanel::selectedModel() const {
  const auto rows = table_->selectionModel()->selectedRows();
  return rows.isEmpty() ? QString() : table_->item(rows.front().row(), kName)->text();
}

void DenoisePanel::setPrecision(nn::Precision p) { precision_->setCurrentIndex(precision_->findData(static_cast<int>(p))); }
nn::Precision DenoisePanel::precision() const { return static_cast<nn::Precision>(precision_->currentData().toInt()); }
void DenoisePanel::setRoiOnly(bool on) { roi_only_->setChecked(on); }
void DenoisePanel::setTile(int64_t tile) {
  const int t = static_cast<int>(std::clamp<int64_t>(tile, 0, 16384));
  if (tile_->findData(t) < 0) tile_->addItem(tr("tile %1").arg(t), t);
  tile_->setCurrentIndex(tile_->findData(t));
}

QString DenoisePanel::cacheKey() const {
  const QString model = selectedModel();
  if (model == "bilateral") return model;
  return QString("%1 %2 %3%4")
      .arg(model, precision_->currentText(), backend_->currentData().toString(),
           QString(energy_->isChecked() ? "" : " raw") + (blend_->isChecked() ? "" : " noblend"));
}

void DenoisePanel::start() {
  if (running() || !session_->hasStack()) return;
  const QString model = selectedModel();
  if (model.isEmpty()) {
    status_->setText(tr("Pick a model first."));
    return;
  }
  const auto stack = session_->stack();
  std::optional<Rect> rect;
  if (roi_only_->isChecked() && roi_ && !roi_->empty()) rect = roi_;
  const QString key = cacheKey();

  // Nothing to run when this model already denoised what is asked for.
  const auto hit = cache_.find(key);
  if (hit != cache_.end() && (hit->second.full || (rect && covered(hit->second.rects, *rect)))) {
    session_->adoptDenoised(hit->second.image, hit->second.description);
    status_->setText(tr("%1: from the cache (already denoised)").arg(hit->second.description));
    emit finished(true, {});
    return;
  }
  // Start from what this model denoised before (a new ROI adds to it), else from the noisy colour.
  preparing_ = true;
  from_noisy_ = hit == cache_.end();
  if (hit != cache_.end()) {
    session_->adoptDenoised(hit->second.image, hit->second.description);
  } else {
    session_->beginDenoised();
  }

  running_key_ = key;
  running_rect_ = rect;
  clock_.start();
  progress_->setRange(0, 0);
  denoise_->setEnabled(false);
  cancel_->setEnabled(true);

  if (model == "bilateral") {
    running_description_ = tr("cross-bilateral filter");
    bilateral_running_ = true;
    preparing_ = false;
    status_->setText(tr("Running the cross-bilateral filter..."));
    emit started(running_description_);
    bilateral_->setFuture(QtConcurrent::run([stack, rect]() {
      try {
        return std::make_shared<Image>(cross_bilateral(*stack, {}, rect));
      } catch (const std::exception&) {
        return std::shared_ptr<Image>();
      }
    }));
    poll_->start();
    return;
  }

  std::shared_ptr<const nn::Model> net;
  QString variant;
  try {
    const auto path = nn::find_model_for(model.toStdString(), feature_set_for(*stack));
    variant = QString::fromStdString(path.stem().string());
    auto& slot = loaded_[QString::fromStdString(path.string())];
    if (!slot) slot = std::make_shared<const nn::Model>(nn::load_model(path));
    net = slot;
  } catch (const std::exception& e) {
    return finish(false, QString::fromStdString(e.what()));
  }
  DenoiseOptions options;
  options.precision = precision();
  options.backend = backend_->currentData().toString().toStdString();
  options.roi = rect;
  options.tile = tile_->currentData().toInt();
  if (options.tile <= 0) options.tile = interactive_tile(net->graph, expectedSecondsPerMp(model));
  options.energy_correction = energy_->isChecked();
  options.variance_blend = blend_->isChecked();
  running_description_ = QString("%1 (%2, %3)").arg(variant, QString::fromStdString(net->architecture()),
                                                    precision_->currentText());
  if (!options.energy_correction) running_description_ += tr(", no energy correction");
  if (stack->variance) running_description_ += options.variance_blend ? tr(", variance blend") : tr(", no variance blend");
  if (variant != model) running_description_ += tr(" — picked for the AOVs this render has");
  status_->setText(tr("Denoising with %1...").arg(running_description_));
  emit started(running_description_);
  // Tiles arrive on the worker thread and are handed to the GUI thread; poll() delivers the queued ones before
  // it ends a job, so none of an old job lands in a new one.
  auto* self = this;
  job_ = std::make_unique<DenoiseJob>(stack, net, options, [self](const Rect& r, const Image& pixels) {
    QMetaObject::invokeMethod(
        self, [self, r, pixels] { if (self->job_) self->session_->setDenoisedTile(r, pixels); }, Qt::QueuedConnection);
  });
  preparing_ = false;
  poll_->start();
}

double DenoisePanel::expectedSecondsPerMp(const QString& model) const {
  if (const auto here = measured_s_per_mp_.find(model); here != measured_s_per_mp_.end()) return here->second;
  for (const auto& m : models_) {
    if (m.name != model) continue;
    const auto bench = precision() == nn::Precision::BF16 ? m.s_per_mp_bf16 : m.s_per_mp_fp32;
    if (bench) return *bench;
    return m.gflop_per_mp / 50.0;  // no benchmark: 50 GFLOP/s, about what 2 cores of fp32 reach here
  }
  return 0.0;
}

double DenoisePanel::progressFraction() const {
  if (!job_) return 0.0;
  const auto p = job_->progress();
  return p.total > 0 ? static_cast<double>(p.done) / static_cast<double>(p.total) : 0.0;
}

void DenoisePanel::cancel() {
  if (job_) job_->cancel();
  if (bilateral_running_) status_->setText(tr("The bilateral filter finishes on its own (it takes a moment)."));
}

void DenoisePanel::poll() {
  const double elapsed = static_cast<double>(clock_.elapsed()) / 1000.0;
  if (!job_) {
    if (bilateral_running_) status_->setText(tr("Running the cross-bilateral filter... %1").arg(duration(elapsed)));
    return;
  }
  const auto p = job_->progress();
  if (p.total > 0) {
    progress_->setRange(0, static_cast<int>(p.total));
    progress_->setValue(static_cast<int>(p.done));
    QString text = tr("%1\ntile %2 of %3, %4 elapsed").arg(running_description_).arg(p.done).arg(p.total).arg(duration(elapsed));
    if (p.done > 0 && p.done < p.total)
      text += tr(", about %1 left").arg(duration(elapsed / static_cast<double>(p.done) * static_cast<double>(p.total - p.done)));
    status_->setText(text);
    emit progressed(p.done, p.total);
  }
  const auto st = job_->status();
  if (st == DenoiseJob::Status::Running) return;
  // Deliver the tiles still queued before the result is taken.
  QCoreApplication::sendPostedEvents(this);
  if (st == DenoiseJob::Status::Done) {
    const auto& stats = job_->stats();
    const Rect r = running_rect_.value_or(job_->result()->bounds());
    // The tiles shown so far are the network's output; the result may differ by the energy correction.
    if (stats.energy_corrected) session_->setDenoisedTile(r, crop(*job_->result(), r));
    const double mp = static_cast<double>(r.area()) / 1e6;
    if (mp > 0 && stats.seconds > 0) measured_s_per_mp_[selectedModel()] = stats.seconds / mp;
    finish(true, {});
  } else if (st == DenoiseJob::Status::Cancelled) {
    finish(false, tr("cancelled: the finished tiles are shown, the rest is the noisy input"));
  } else {
    finish(false, QString::fromStdString(job_->error()));
  }
}

void DenoisePanel::finish(bool ok, const QString& message) {
  preparing_ = false;
  poll_->stop();
  const double elapsed = static_cast<double>(clock_.elapsed()) / 1000.0;
  if (job_) job_->wait();
  job_.reset();
  denoise_->setEnabled(true);
  cancel_->setEnabled(false);
  progress_->setRange(0, 1);
  progress_->setValue(ok ? 1 : 0);
  if (ok && session_->denoised()) {
    auto& entry = cache_[running_key_];
    entry.image = session_->denoisedForCache();  // shared, not copied
    entry.description = running_description_;
    if (running_rect_) entry.rects.push_back(*running_rect_);
    else entry.full = true;
    session_->adoptDenoised(entry.image, running_description_);
    status_->setText(tr("%1: done in %2%3")
                         .arg(running_description_, duration(elapsed),
                              running_rect_ ? tr(" (ROI %1)").arg(QString::fromStdString(running_rect_->to_string()))
                                            : QString()));
    fillTable();
    selectModel(running_key_.section(' ', 0, 0));
  } else {
    status_->setText(message);
  }
  emit finished(ok, message);
}

}  // namespace residue::ui
