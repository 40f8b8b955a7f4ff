#include "ui/metrics_panel.h"

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QHeaderView>
#include <QLabel>
#include <QScrollBar>
#include <QTableWidget>
#include <QVBoxLayout>
#include <cmath>

namespace residue::ui {

namespace {
enum Column { kRelMse, kSsim, kPsnr, kMse, kPixels, kExcluded, kColumns };

QString number(double v, int precision) {
  if (std::isnan(v)) return QStringLiteral("n/a");
  if (std::isinf(v)) return v > 0 ? QStringLiteral("inf") : QStringLiteral("-inf");
  return QString::number(v, 'g', precision);
}
}  // namespace

MetricsPanel::MetricsPanel(QWidget* parent) : QWidget(parent) {
  auto* layout = new QVBoxLayout(this);
  scope_ = new QLabel(tr("No reference"), this);
  scope_->setObjectName("metricsScope");
  layout->addWidget(scope_);

  table_ = new QTableWidget(0, kColumns, this);
  table_->setObjectName("metricsTable");
  table_->setHorizontalHeaderLabels({tr("relMSE"), tr("SSIM"), tr("PSNR dB"), tr("MSE"), tr("pixels"),
                                     tr("excluded")});
  table_->setEditTriggers(QAbstractItemView::NoEditTriggers);
  table_->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  table_->verticalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  table_->setSizeAdjustPolicy(QAbstractScrollArea::AdjustToContents);
  // Both rows (noisy, denoised) stay in view however the docks are squeezed.
  table_->setMinimumHeight(table_->horizontalHeader()->sizeHint().height() + 2 * table_->verticalHeader()->defaultSectionSize() +
                           table_->horizontalScrollBar()->sizeHint().height() + 4);
  layout->addWidget(table_);

  counts_ = new QLabel(this);
  counts_->setObjectName("metricsCounts");
  counts_->setWordWrap(true);
  layout->addWidget(counts_);

  auto* form = new QFormLayout;
  eps_ = new QDoubleSpinBox(this);
  eps_->setObjectName("metricsEps");
  eps_->setDecimals(6);
  eps_->setRange(1e-6, 10.0);
  eps_->setSingleStep(0.001);
  eps_->setValue(metrics::Options{}.eps);
  eps_->setToolTip(tr("relMSE = mean (x - r)^2 / (r^2 + eps)"));
  form->addRow(tr("relMSE eps"), eps_);
  space_ = new QComboBox(this);
  space_->setObjectName("metricsSpace");
  space_->addItem(tr("tonemapped (Hable filmic + sRGB)"));
  space_->addItem(tr("linear"));
  space_->setToolTip(tr("The values SSIM and PSNR are computed on"));
  form->addRow(tr("SSIM/PSNR on"), space_);
  layout->addLayout(form);
  layout->addStretch(1);

  connect(eps_, &QDoubleSpinBox::valueChanged, this, &MetricsPanel::optionsChanged);
  connect(space_, &QComboBox::currentIndexChanged, this, &MetricsPanel::optionsChanged);

  task_ = std::make_unique<LatestTask<Computed>>(this, [this](Computed&& r) {
    report_ = std::move(r.report);
    error_ = r.error;
    showReport();
    emit computed();
  });
  setToolTip(QString::fromStdString(metrics::formula_text(options())));
}

MetricsPanel::~MetricsPanel() = default;

metrics::Options MetricsPanel::options() const {
  metrics::Options o;
  o.eps = eps_->value();
  o.ssim_space = space_->currentIndex() == 1 ? metrics::SsimSpace::Linear : metrics::SsimSpace::Tonemapped;
  return o;
}

// Until the newest result is shown, not only computed: a caller that waits on busy() then reads report().
bool MetricsPanel::busy() const { return task_->busy(); }

void MetricsPanel::compute(Inputs inputs) {
  last_ = inputs;
  metrics::Options o = options();
  o.roi = inputs.roi;
  setToolTip(QString::fromStdString(metrics::formula_text(o)));
  if (!inputs.reference) {
    task_->supersede();
    report_ = {};
    error_.clear();
    scope_->setText(tr("No reference: open one with File > Open Reference"));
    table_->setRowCount(0);
    counts_->clear();
    emit computed();
    return;
  }
  scope_->setText(tr("Computing..."));
  task_->start([inputs, o](const LatestTask<Computed>::Token&) {
    Computed c;
    io::MetricsReport* r = &c.report;
    r->reference_file = inputs.reference_file.toStdString();
    r->width = inputs.reference->width();
    r->height = inputs.reference->height();
    r->options = o;
    try {
      if (inputs.noisy)
        r->rows.push_back({"noisy", inputs.noisy_file.toStdString(), metrics::compare(*inputs.noisy, *inputs.reference, o)});
      if (inputs.denoised)
        r->rows.push_back(
            {"denoised", inputs.denoised_file.toStdString(), metrics::compare(*inputs.denoised, *inputs.reference, o)});
    } catch (const std::exception& e) {
      r->rows.clear();
      c.error = QString::fromStdString(e.what());
    }
    return c;
  });
}

void MetricsPanel::showReport() {
  const auto& o = report_.options;
  if (!error_.isEmpty()) {
    scope_->setText(error_);
    table_->setRowCount(0);
    return;
  }
  scope_->setText(o.roi ? tr("ROI x %1, y %2, %3 x %4")
                              .arg(o.roi->x).arg(o.roi->y).arg(o.roi->width).arg(o.roi->height)
                        : tr("Whole image, %1 x %2").arg(report_.width).arg(report_.height));
  table_->setRowCount(static_cast<int>(report_.rows.size()));
  QStringList names;
  for (size_t i = 0; i < report_.rows.size(); ++i) {
    const auto& row = report_.rows[i];
    const auto& s = row.scores;
    names << QString::fromStdString(row.name);
    const int r = static_cast<int>(i);
    table_->setItem(r, kRelMse, new QTableWidgetItem(number(s.relmse, 5)));
    table_->setItem(r, kSsim, new QTableWidgetItem(number(s.ssim, 5)));
    table_->setItem(r, kPsnr, new QTableWidgetItem(number(s.psnr, 4)));
    table_->setItem(r, kMse, new QTableWidgetItem(number(s.mse, 5)));
    table_->setItem(r, kPixels, new QTableWidgetItem(QString::number(s.pixels)));
    auto* ex = new QTableWidgetItem(QString::number(s.excluded_test + s.excluded_reference));
    ex->setToolTip(tr("pixels left out: %1 not finite in this image, %2 not finite in the reference")
                       .arg(s.excluded_test).arg(s.excluded_reference));
    table_->setItem(r, kExcluded, ex);
  }
  table_->setVerticalHeaderLabels(names);
  const QString formula = QString::fromStdString(metrics::formula_text(o));
  for (int r = 0; r < table_->rowCount(); ++r)
    for (int c = 0; c < kRelMse + 4; ++c)
      if (auto* item = table_->item(r, c)) item->setToolTip(formula);
  QString counts = tr("Non-finite values: noisy %1 NaN, %2 Inf; reference %3 NaN, %4 Inf")
                       .arg(last_.noisy_nan).arg(last_.noisy_inf).arg(last_.reference_nan).arg(last_.reference_inf);
  if (report_.rows.size() == 2 && report_.rows[1].scores.relmse > 0)
    counts.prepend(tr("Denoised relMSE is %1x lower than noisy.\n")
                       .arg(report_.rows[0].scores.relmse / report_.rows[1].scores.relmse, 0, 'f', 1));
  counts_->setText(counts);
}

}  // namespace residue::ui
