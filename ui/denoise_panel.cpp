#include "ui/denoise_panel.h"

#include <QCheckBox>
#include <QCoreApplication>
#include <QComboBox>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QProgressBar>
#include <QPushButton>
#include <QSignalBlocker>
#include <QSlider>
#include <QTableWidget>
#include <QTimer>
#include <QVBoxLayout>
#include <cmath>

#include "core/nn/backend.h"
#include "ui/session.h"

namespace residue::ui {

namespace {
enum Column { kName, kCost, kBench, kHere, kRelMse, kSsim, kColumns };

QString opt(const std::optional<double>& v, int precision, const QString& suffix = {}) {
  return v ? QString::number(*v, 'g', precision) + suffix : QStringLiteral("-");
}

QString duration(double seconds) {
  if (seconds < 60) return QString::number(seconds, 'f', 1) + " s";
  return QString("%1 min %2 s").arg(static_cast<int>(seconds / 60)).arg(static_cast<int>(seconds) % 60);
}

}  // namespace

DenoisePanel::DenoisePanel(Session* session, QWidget* parent) : QWidget(parent), session_(session) {
  auto* layout = new QVBoxLayout(this);
  table_ = new QTableWidget(0, kColumns, this);
  table_->setObjectName("modelTable");
  table_->setHorizontalHeaderLabels({tr("model"), tr("GFLOP"), tr("s/MP"), tr("here"), tr("relMSE"), tr("SSIM")});
  const QStringList header_tips = {
      tr("The model family; the variant for the render's AOVs is picked when it runs"),
      tr("Network work per megapixel: billions of floating-point operations (a multiply-add is two)"),
      tr("Seconds per megapixel at the chosen precision, as benchmarked (the model file says on which CPU)"),
      tr("Seconds per megapixel measured on this machine, once the model has run here"),
      tr("Mean relMSE on the validation scenes (lower is better)"),
      tr("Mean SSIM on the validation scenes (higher is better)")};
  for (int c = 0; c < kColumns; ++c) table_->horizontalHeaderItem(c)->setToolTip(header_tips[c]);
  table_->setSelectionBehavior(QAbstractItemView::SelectRows);
  table_->setSelectionMode(QAbstractItemView::SingleSelection);
  table_->setEditTriggers(QAbstractItemView::NoEditTriggers);
  table_->verticalHeader()->hide();
  table_->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  table_->horizontalHeader()->setSectionResizeMode(kName, QHeaderView::Stretch);
  table_->setToolTip(tr("Speed against accuracy: seconds per megapixel as benchmarked (model file) and as "
                        "measured on this machine; relMSE and SSIM on the validation scenes."));
  layout->addWidget(table_, 1);
  auto* caption = new QLabel(tr("GFLOP per megapixel; s/MP: seconds per megapixel as benchmarked, here: as "
                                "measured on this machine; relMSE, SSIM: on the validation scenes."), this);
  caption->setWordWrap(true);
  caption->setObjectName("modelTableCaption");
  layout->addWidget(caption);

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
  ensemble_ = new QComboBox(this);
  ensemble_->setObjectName("ensemble");
  ensemble_->addItem(tr("model's ensemble"), 0);
  for (int n : {1, 2, 4, 8}) ensemble_->addItem(tr("x%1").arg(n), n);
  ensemble_->setToolTip(tr("Self-ensemble: run the network on the image flipped and transposed (1, 2, 4 or 8 ways) "
                           "and average; N times the time for a lower error (see docs/MODELS.md)"));
  row->addWidget(ensemble_);
  layout->addLayout(row);
  row = new QHBoxLayout;  // two rows: the panel fits a narrow side bar
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
  strength_->setToolTip(tr("Denoising strength of A: 100 % is the denoised result, 0 % the noisy input, between a "
                           "linear blend of the two (which keeps the brightness), kept as a result of its own beside "
                           "the full one (\"oidn fp32 @ 50 %\") with its own scores, heatmap and export."));
  strength_row->addWidget(strength_label_);
  strength_row->addWidget(strength_, 1);
  layout->addLayout(strength_row);
  connect(strength_, &QSlider::valueChanged, this, [this](int v) {
    strength_label_->setText(tr("Strength %1 %").arg(v));
    session_->setStrength(static_cast<float>(v) / 100.0f);
  });
  // The slider shows A's strength: 100 % for a full result, its own for a result at a strength.
  connect(session_, &Session::denoisedChanged, this, [this] {
    const int v = static_cast<int>(std::lround(session_->strength() * 100.0f));
    if (v == strength_->value()) return;
    const QSignalBlocker block(strength_);
    strength_->setValue(v);
    strength_label_->setText(tr("Strength %1 %").arg(v));
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

  connect(denoise_, &QPushButton::clicked, this, &DenoisePanel::start);
  connect(cancel_, &QPushButton::clicked, this, &DenoisePanel::cancel);

  QStringList problems;
  std::vector<std::string> card_problems;
  controller_ = new DenoiseController(session_, nn::list_model_cards(&card_problems), this);
  for (const auto& p : card_problems) problems << QString::fromStdString(p);
  tick_ = new QTimer(this);
  tick_->setInterval(200);
  connect(tick_, &QTimer::timeout, this, &DenoisePanel::showProgress);
  connect(controller_, &DenoiseController::started, this, [this](const QString& what) {
    progress_->setRange(0, 0);
    denoise_->setEnabled(false);
    cancel_->setEnabled(true);
    status_->setText(tr("Denoising with %1...").arg(what));
    tick_->start();
    emit started(what);
  });
  connect(controller_, &DenoiseController::progressed, this, [this](int64_t done, int64_t total) {
    showProgress();
    emit progressed(done, total);
  });
  connect(controller_, &DenoiseController::finished, this, [this](bool ok, const QString& message) {
    tick_->stop();
    denoise_->setEnabled(true);
    cancel_->setEnabled(false);
    progress_->setRange(0, 1);
    progress_->setValue(ok ? 1 : 0);
    const Result* a = session_->result(session_->a());
    if (ok && a) {
      status_->setText(message.isEmpty() ? tr("%1: done in %2").arg(a->description, duration(a->seconds)) : message);
      fillTable();
    } else {
      status_->setText(message);
    }
    emit finished(ok, message);
  });
  // Another render (or frame): the last run's "done in ..." and its bar were about the one before.
  connect(session_, &Session::loaded, this, [this] {
    if (controller_->running()) return;
    progress_->setRange(0, 1);
    progress_->setValue(0);
    status_->clear();
  });
  connect(precision_, &QComboBox::currentIndexChanged, this, &DenoisePanel::fillTable);
  fillTable();
  selectModel(nn::kDefaultModel);
  if (!problems.isEmpty()) status_->setText(problems.join("\n"));
}

DenoisePanel::~DenoisePanel() = default;

void DenoisePanel::fillTable() {
  const auto& models = controller_->models();
  table_->setRowCount(static_cast<int>(models.size()));
  for (size_t i = 0; i < models.size(); ++i) {
    const auto& m = models[i];
    const int r = static_cast<int>(i);
    const QString family = QString::fromStdString(m.family);
    auto* name = new QTableWidgetItem(family);
    QStringList variants;
    for (const auto& v : m.variants) variants << QString::fromStdString(v);
    QString tip = QString::fromStdString(m.architecture);
    if (!m.file.empty()) tip += "\n" + QString::fromStdString(m.file.string());
    if (!variants.isEmpty()) tip += tr("\nvariants: %1").arg(variants.join(", "));
    if (!m.description.empty()) tip += "\n" + QString::fromStdString(m.description);
    name->setToolTip(tip);
    table_->setItem(r, kName, name);
    const bool network = m.method != nn::Method::Bilateral;
    table_->setItem(r, kCost, new QTableWidgetItem(network ? QString::number(m.gflop_per_mp, 'f', 0) : QString("-")));
    auto* bench = new QTableWidgetItem(opt(m.seconds_per_mp(precision()), 3));
    if (m.benchmark)
      bench->setToolTip(tr("fp32 %1, bf16 %2 s/MP, benchmarked on %3")
                            .arg(opt(m.benchmark->fp32_s_per_mp, 3), opt(m.benchmark->bf16_s_per_mp, 3),
                                 QString::fromStdString(m.benchmark->machine)));
    table_->setItem(r, kBench, bench);
    // Measured per member of a self-ensemble; shown for the ensemble the card is for, as its s/MP column.
    const auto here = controller_->measuredSecondsPerMp(family);
    table_->setItem(r, kHere, new QTableWidgetItem(opt(here ? std::optional<double>(*here * m.ensemble) : std::nullopt, 3)));
    const auto& val = m.validation;
    auto* rel = new QTableWidgetItem(val ? QString::number(val->relmse, 'g', 3) : QString("-"));
    auto* ssim = new QTableWidgetItem(val ? QString::number(val->ssim, 'g', 4) : QString("-"));
    if (val) {
      const QString scenes = tr("mean over %1 validation scenes").arg(val->scenes);
      rel->setToolTip(val->noisy_relmse ? tr("%1; noisy input: %2").arg(scenes).arg(*val->noisy_relmse, 0, 'g', 3) : scenes);
      ssim->setToolTip(scenes);
    }
    table_->setItem(r, kRelMse, rel);
    table_->setItem(r, kSsim, ssim);
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

DenoiseController::Request DenoisePanel::request() const {
  DenoiseController::Request r;
  r.model = selectedModel();
  r.precision = precision();
  r.backend = backend_->currentData().toString();
  r.tile = tile_->currentData().toInt();
  r.energy_correction = energy_->isChecked();
  r.variance_blend = blend_->isChecked();
  r.ensemble = ensemble_->currentData().toInt();
  if (roi_only_->isChecked() && roi_ && !roi_->empty()) r.roi = roi_;
  return r;
}

void DenoisePanel::start() {
  if (running() || !session_->hasStack()) return;
  controller_->start(request());
}

double DenoisePanel::expectedSecondsPerMp(const QString& model) const {
  return controller_->expectedSecondsPerMp(model, precision());
}

double DenoisePanel::progressFraction() const {
  const auto p = controller_->progress();
  return p.fraction;
}

void DenoisePanel::cancel() {
  controller_->cancel();
}

void DenoisePanel::showProgress() {
  if (!controller_->running()) return;
  const auto p = controller_->progress();
  QString text = controller_->runningDescription();
  if (p.total > 0) {
    progress_->setRange(0, 1000);
    progress_->setValue(static_cast<int>(p.fraction * 1000.0));
    text += (p.preliminary ? tr("\nfirst passes (prefilter or prior): tile %1 of %2, %3 elapsed")
                           : tr("\ntile %1 of %2, %3 elapsed"))
                .arg(p.done)
                .arg(p.total)
                .arg(duration(p.elapsed));
    if (p.left >= 0) text += tr(", about %1 left").arg(duration(p.left));
  } else {
    text += tr("\n%1 elapsed").arg(duration(p.elapsed));
  }
  status_->setText(text);
}

}  // namespace residue::ui
