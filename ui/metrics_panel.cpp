#include "ui/metrics_panel.h"

#include "core/metrics/flip.h"

#include <QApplication>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFileInfo>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QPushButton>
#include <QTableWidget>
#include <QVBoxLayout>
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/metrics/flip.h"
#include "core/metrics/temporal.h"
#include "core/temporal/warped_error.h"

namespace residue::ui {

namespace {
enum Column { kNumber, kAB, kName, kRelMse, kSsim, kFlip, kTemporal, kPsnr, kTime, kRoiRelMse, kRoiSsim, kRoiFlip, kRoiPsnr, kColumns };

QString number(double v, int precision) {
  if (std::isnan(v)) return QStringLiteral("n/a");
  if (std::isinf(v)) return v > 0 ? QStringLiteral("inf") : QStringLiteral("-inf");
  return QString::number(v, 'g', precision);
}

// Sorts by the number it shows (text would put 1e-05 after 0.002); unknown values last.
class NumberItem : public QTableWidgetItem {
 public:
  NumberItem(const QString& text, double value) : QTableWidgetItem(text) { setData(Qt::UserRole, value); }
  bool operator<(const QTableWidgetItem& other) const override {
    const double a = data(Qt::UserRole).toDouble(), b = other.data(Qt::UserRole).toDouble();
    if (std::isnan(a) || std::isnan(b)) return !std::isnan(a) && std::isnan(b);
    return a < b;
  }
};

constexpr int kIdRole = Qt::UserRole + 1;  // the result's id, on the name cell (UserRole is its sort key)
constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();
}  // namespace

MetricsPanel::MetricsPanel(QWidget* parent) : QWidget(parent) {
  auto* layout = new QVBoxLayout(this);
  scope_ = new QLabel(tr("No reference"), this);
  scope_->setObjectName("metricsScope");
  scope_->setWordWrap(true);
  layout->addWidget(scope_);

  table_ = new QTableWidget(0, kColumns, this);
  table_->setObjectName("metricsTable");
  table_->setHorizontalHeaderLabels({tr("#"), QString(), tr("result"), tr("relMSE"), tr("SSIM"), tr("HDR-FLIP"), tr("temporal"),
                                     tr("PSNR"), tr("time"), tr("ROI relMSE"), tr("ROI SSIM"), tr("ROI FLIP"), tr("ROI PSNR")});
  const QStringList tips = {tr("The key that shows the result as A (Ctrl+key: as B), in the order the rows are shown"),
                            tr("A: the denoised pane; B: the one compared with it"),
                            tr("What made the image: model and precision, or the file it came from"),
                            tr("relMSE = mean (x - r)\u00b2 / (r\u00b2 + eps) over the whole image (lower is better)"),
                            tr("SSIM over the whole image (higher is better)"),
                            tr("HDR-FLIP: NVIDIA's FLIP error, what a viewer notices when flipping between the result "
                               "and the reference, over the reference's exposures (lower is better; computed after "
                               "the other scores)"),
                            tr("Temporal error along the motion: how much the error changed since frame t-1 on the "
                               "same surfaces, relMSE-like (frame t-1's error warped to this frame; pixels it does "
                               "not show are left out). Lower is steadier. Needs this result on frame t-1 too."),
                            tr("PSNR in dB over the whole image (higher is better)"),
                            tr("Seconds the run took here"),
                            tr("relMSE in the dragged region"),
                            tr("SSIM in the dragged region"),
                            tr("HDR-FLIP in the dragged region (the whole image's map, averaged over the region)"),
                            tr("PSNR in the dragged region")};
  for (int c = 0; c < kColumns; ++c) table_->horizontalHeaderItem(c)->setToolTip(tips[c]);
  table_->setEditTriggers(QAbstractItemView::NoEditTriggers);
  table_->setSelectionBehavior(QAbstractItemView::SelectRows);
  table_->setSelectionMode(QAbstractItemView::SingleSelection);
  table_->verticalHeader()->hide();
  table_->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  // The name gets the width it needs (up to a limit, then elided), the scores theirs; a narrow side bar scrolls
  // sideways rather than squeezing the names to a few letters.
  table_->horizontalHeader()->setSectionResizeMode(kName, QHeaderView::Interactive);
  table_->horizontalHeader()->setStretchLastSection(true);
  // A region's scores come right after the names (they are what a dragged region is for), so that a side bar
  // shows a result's name and its region scores together; the whole image's follow, scrolled to when wanted.
  for (int c : {kRoiRelMse, kRoiSsim, kRoiFlip, kRoiPsnr})
    table_->horizontalHeader()->moveSection(table_->horizontalHeader()->visualIndex(c),
                                            table_->horizontalHeader()->visualIndex(kName) + 1 + (c - kRoiRelMse));
  table_->setSortingEnabled(true);
  table_->sortByColumn(kName, Qt::AscendingOrder);  // the order the results came in
  // After every sort (a header click, or the table refilled): the model reorders its rows, then says so.
  connect(table_->model(), &QAbstractItemModel::layoutChanged, this, [this] { numberRows(); });
  table_->setWordWrap(false);
  table_->setTextElideMode(Qt::ElideMiddle);
  layout->addWidget(table_, 1);

  auto* buttons = new QHBoxLayout;
  auto* add = new QPushButton(tr("Add..."), this);
  add->setObjectName("addResultButton");
  add->setToolTip(tr("Add an image to compare: another denoiser's output, an earlier render (File > Add Result)"));
  set_b_ = new QPushButton(tr("Show as B"), this);
  set_b_->setObjectName("setBButton");
  set_b_->setToolTip(tr("Compare the selected result with A (Ctrl+click a row; Ctrl+1-9)"));
  remove_ = new QPushButton(tr("Remove"), this);
  remove_->setObjectName("removeResultButton");
  buttons->addWidget(add);
  buttons->addWidget(set_b_);
  buttons->addWidget(remove_);
  layout->addLayout(buttons);
  connect(add, &QPushButton::clicked, this, &MetricsPanel::addRequested);
  connect(set_b_, &QPushButton::clicked, this, [this] {
    if (const int id = selectedId(); id >= 0) emit showAsB(id);
  });
  connect(remove_, &QPushButton::clicked, this, [this] {
    if (const int id = selectedId(); id >= 0) emit removeRequested(id);
  });
  // Up/Down (or any change of the current row that is not the table being refilled) shows that row as A.
  connect(table_, &QTableWidget::currentCellChanged, this, [this](int row, int, int previous, int) {
    if (updating_ || row < 0 || row == previous || !table_->item(row, kName)) return;
    if (QApplication::mouseButtons() != Qt::NoButton) return;  // a click: cellClicked decides (A, or B with Ctrl)
    const int id = table_->item(row, kName)->data(kIdRole).toInt();
    if (id >= 0) emit showAsA(id);
  });
  connect(table_, &QTableWidget::cellClicked, this, [this](int row, int) {
    const int id = table_->item(row, kName)->data(kIdRole).toInt();
    if (id < 0) return;
    if (QApplication::keyboardModifiers() & Qt::ControlModifier) emit showAsB(id);
    else emit showAsA(id);
  });

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

  connect(eps_, &QDoubleSpinBox::valueChanged, this, &MetricsPanel::optionsChanged);
  connect(space_, &QComboBox::currentIndexChanged, this, &MetricsPanel::optionsChanged);

  task_ = std::make_unique<LatestTask<Computed>>(this, [this](Computed&& r) {
    error_ = r.error;
    known_.merge(r.scores);
    temporal_.merge(r.temporal);
    showTable();
    computeFlip();  // the slow score once the others are shown
    emit computed();
  });
  flip_task_ = std::make_unique<LatestTask<FlipComputed>>(this, [this](FlipComputed&& r) {
    flips_.merge(r.flips);
    flips_pending_.clear();
    showTable();
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
bool MetricsPanel::busy() const { return task_->busy() || flip_task_->busy(); }

std::shared_ptr<const Image> MetricsPanel::flipMap(const Image* image) const {
  const auto it = flips_.find(image);
  return it == flips_.end() ? nullptr : it->second.map;
}

std::vector<int> MetricsPanel::visibleIds() const {
  std::vector<int> ids;
  for (int r = 0; r < table_->rowCount(); ++r)
    if (const auto* name = table_->item(r, kName); name && name->data(kIdRole).toInt() >= 0)
      ids.push_back(name->data(kIdRole).toInt());
  return ids;
}

void MetricsPanel::numberRows() {
  if (numbering_) return;  // setting the # items may re-sort when the table is sorted by them
  numbering_ = true;
  int n = 0;
  for (int r = 0; r < table_->rowCount(); ++r) {
    const auto* name = table_->item(r, kName);
    const bool result = name && name->data(kIdRole).toInt() >= 0;
    if (result) ++n;
    const QString text = result && n <= 9 ? QString::number(n) : QString();
    if (auto* item = table_->item(r, kNumber); item && item->text() == text) continue;
    auto* item = new QTableWidgetItem(text);
    item->setData(Qt::UserRole, kUnknown);
    table_->setItem(r, kNumber, item);
  }
  numbering_ = false;
}

int MetricsPanel::selectedId() const {
  const auto rows = table_->selectionModel()->selectedRows();
  if (rows.isEmpty()) return -1;
  return table_->item(rows.front().row(), kName)->data(kIdRole).toInt();
}

void MetricsPanel::compute(Inputs inputs) {
  last_ = inputs;
  const metrics::Options o = options();
  setToolTip(QString::fromStdString(metrics::formula_text(o)));
  // Scores are kept per image; another reference or other settings make them all new.
  if (inputs.reference.get() != known_reference_ || o.eps != known_options_.eps ||
      o.ssim_space != known_options_.ssim_space) {
    known_.clear();
    temporal_.clear();
    if (inputs.reference.get() != known_reference_) flips_.clear();  // FLIP has no eps nor space
    known_reference_ = inputs.reference.get();
    known_options_ = o;
  }
  if (!inputs.reference) {
    task_->supersede();
    flip_task_->supersede();
    flips_pending_.clear();
    error_.clear();
    scope_->setText(tr("No reference: open one with File > Open Reference; the results are listed without scores"));
    showTable();
    emit computed();
    return;
  }
  std::vector<std::pair<Key, std::shared_ptr<const Image>>> todo;
  for (const auto& row : inputs.rows) {
    if (!row.image) continue;
    // The whole image always; the region where it lies inside the image (so it can never blank the whole
    // image's scores).
    std::vector<Rect> regions = {row.image->bounds()};
    if (inputs.roi && !inputs.roi->empty() && row.image->bounds().contains(*inputs.roi)) regions.push_back(*inputs.roi);
    for (const Rect& r : regions) {
      const Key k{row.image.get(), r.x, r.y, r.width, r.height};
      if (!known_.count(k)) todo.emplace_back(k, row.image);
    }
  }
  std::vector<std::pair<Pair, KnownTemporal>> pairs;  // temporal errors not known yet
  const bool temporal = inputs.frame && inputs.previous_frame && inputs.frame->motion && inputs.frame->reference &&
                        inputs.previous_frame->reference;
  if (temporal)
    for (const auto& row : inputs.rows)
      if (row.image && row.previous && !temporal_.count({row.image.get(), row.previous.get()}))
        pairs.push_back({{row.image.get(), row.previous.get()}, {row.image, row.previous, kUnknown}});
  showTable();  // the rows at once, scores as they are known
  if (todo.empty() && pairs.empty()) {
    task_->supersede();
    computeFlip();
    emit computed();
    return;
  }
  scope_->setText(tr("Computing..."));
  const auto reference = inputs.reference;
  const auto frame = inputs.frame, previous_frame = inputs.previous_frame;
  task_->start([todo, pairs, reference, frame, previous_frame, o](const LatestTask<Computed>::Token& token) {
    Computed c;
    try {
      for (const auto& [k, image] : todo) {
        if (token.superseded()) break;
        metrics::Options ko = o;
        const Rect region{k.x, k.y, k.w, k.h};
        if (region != image->bounds()) ko.roi = region;
        c.scores[k] = {image, metrics::compare(*image, *reference, ko)};
      }
      for (auto [k, known] : pairs) {  // the mean of the map core's `eval` on a sequence averages too
        if (token.superseded()) break;
        metrics::CompensatedTemporalRelMse m(o.eps);
        m.add_map(compensated_temporal_map(*frame, *known.image, *previous_frame, *known.previous, o.eps));
        known.value = m.value();
        c.temporal[k] = known;
      }
    } catch (const std::exception& e) {
      c.scores.clear();
      c.error = QString::fromStdString(e.what());
    }
    return c;
  });
}

// HDR-FLIP of every result that has none yet, one map each, on a worker thread; a job already computing the same
// results is left to finish (a region dragged meanwhile only averages the maps again).
void MetricsPanel::computeFlip() {
  const auto& in = last_;
  if (!in.reference) return;
  std::vector<std::shared_ptr<const Image>> need;
  std::vector<const Image*> keys;
  for (const auto& row : in.rows)
    if (row.image && !flips_.count(row.image.get()) && row.image->width() == in.reference->width() &&
        row.image->height() == in.reference->height() &&
        std::find(keys.begin(), keys.end(), row.image.get()) == keys.end()) {
      need.push_back(row.image);
      keys.push_back(row.image.get());
    }
  if (keys == flips_pending_ && flip_task_->busy()) return;
  flips_pending_ = keys;
  if (need.empty()) {
    flip_task_->supersede();
    return;
  }
  const auto reference = in.reference;
  flip_task_->start([need, reference](const LatestTask<FlipComputed>::Token& token) {
    FlipComputed c;
    for (const auto& image : need) {
      if (token.superseded()) break;
      try {
        metrics::FlipResult r = metrics::hdr_flip(*image, *reference);
        c.flips[image.get()] = {image, std::make_shared<const Image>(std::move(r.map)), r.mean, r.exposures};
      } catch (const std::exception&) {  // a reference without light has no exposures: no FLIP, shown as n/a
        c.flips[image.get()] = {image, nullptr, kUnknown, {}};
      }
    }
    return c;
  });
}

void MetricsPanel::showTable() {
  const auto& in = last_;
  metrics::Options o = options();
  // The reports, from what is known.
  const auto fill = [&](io::MetricsReport& report, const std::optional<Rect>& roi) {
    report = {};
    if (!in.reference) return;
    report.reference_file = in.reference_file.toStdString();
    report.width = in.reference->width();
    report.height = in.reference->height();
    report.options = o;
    report.options.roi = roi;
    for (const auto& row : in.rows) {
      if (!row.image) continue;
      const Rect r = roi.value_or(row.image->bounds());
      const auto it = known_.find({row.image.get(), r.x, r.y, r.width, r.height});
      if (it == known_.end()) continue;
      std::string name = row.id < 0 ? "noisy" : row.name.toStdString();
      report.rows.push_back({name, row.file.toStdString(), it->second.scores});
      if (const auto f = flips_.find(row.image.get()); f != flips_.end() && f->second.map) {
        report.rows.back().hdr_flip = roi ? metrics::flip_mean(*f->second.map, roi) : f->second.mean;
        report.flip = f->second.exposures;
      }
      if (!roi && row.previous)  // the table's temporal column: the whole image's
        if (const auto t = temporal_.find({row.image.get(), row.previous.get()}); t != temporal_.end())
          report.rows.back().temporal_relmse_compensated = t->second.value;
    }
  };
  fill(whole_, std::nullopt);
  if (in.roi) fill(report_, in.roi);
  else report_ = whole_;

  if (!error_.isEmpty()) scope_->setText(error_);
  else if (in.reference)
    scope_->setText(in.roi ? tr("Scores of the whole %1 x %2 image and of the region x %3, y %4, %5 x %6")
                                 .arg(in.reference->width()).arg(in.reference->height())
                                 .arg(in.roi->x).arg(in.roi->y).arg(in.roi->width).arg(in.roi->height)
                           : tr("Scores of the whole %1 x %2 image against %3")
                                 .arg(in.reference->width()).arg(in.reference->height())
                                 .arg(QFileInfo(in.reference_file).fileName()));

  updating_ = true;
  const int sort_column = table_->horizontalHeader()->sortIndicatorSection();
  const auto sort_order = table_->horizontalHeader()->sortIndicatorOrder();
  table_->setSortingEnabled(false);
  table_->setRowCount(static_cast<int>(in.rows.size()));
  const QString formula = QString::fromStdString(metrics::formula_text(o));
  int a_row = -1;
  const bool temporal_on = in.frame && in.previous_frame && in.frame->motion && in.frame->reference &&
                           in.previous_frame->reference;
  for (size_t i = 0; i < in.rows.size(); ++i) {
    const auto& row = in.rows[i];
    const int r = static_cast<int>(i);
    auto* ab = new NumberItem(row.a ? "A" : row.b ? "B" : "", row.a ? 0 : row.b ? 1 : 2);
    table_->setItem(r, kAB, ab);
    auto* name = new NumberItem(row.state.isEmpty() ? row.name : QString("%1 (%2)").arg(row.name, row.state),
                                static_cast<double>(i));
    name->setData(kIdRole, row.id);
    {
      const QString what = row.description.isEmpty() ? row.file : row.description;
      name->setToolTip(row.state_text.isEmpty() ? what : row.state_text + "\n" + what);
    }
    table_->setItem(r, kName, name);
    const auto scores = [&](const std::optional<Rect>& roi) -> const metrics::Scores* {
      if (!row.image) return nullptr;
      const Rect rr = roi.value_or(row.image->bounds());
      const auto it = known_.find({row.image.get(), rr.x, rr.y, rr.width, rr.height});
      return it == known_.end() ? nullptr : &it->second.scores;
    };
    const auto put = [&](int column, const metrics::Scores* s, double metrics::Scores::*field, int digits) {
      const double v = s ? s->*field : kUnknown;
      auto* item = new NumberItem(s ? number(v, digits) : QString(row.image && in.reference ? "..." : "-"), v);
      if (s) item->setToolTip(tr("%1\n%2 pixels, %3 left out (not finite)")
                                  .arg(formula).arg(s->pixels).arg(s->excluded_test + s->excluded_reference));
      table_->setItem(r, column, item);
    };
    const auto* whole = scores(std::nullopt);
    put(kRelMse, whole, &metrics::Scores::relmse, 5);
    put(kSsim, whole, &metrics::Scores::ssim, 5);
    put(kPsnr, whole, &metrics::Scores::psnr, 4);
    const auto* roi = in.roi ? scores(in.roi) : nullptr;
    put(kRoiRelMse, roi, &metrics::Scores::relmse, 5);
    put(kRoiSsim, roi, &metrics::Scores::ssim, 5);
    put(kRoiPsnr, roi, &metrics::Scores::psnr, 4);
    {
      const auto it = row.image ? flips_.find(row.image.get()) : flips_.end();
      const bool known = it != flips_.end();
      const auto put_flip = [&](int column, const std::optional<Rect>& region) {
        double v = kUnknown;
        if (known && it->second.map && (!region || it->second.map->bounds().contains(*region)))
          v = region ? metrics::flip_mean(*it->second.map, region) : it->second.mean;
        auto* item = new NumberItem(known ? number(v, 4) : QString(row.image && in.reference ? "..." : "-"), v);
        if (known && it->second.map)
          item->setToolTip(QString::fromStdString(metrics::flip_formula_text(it->second.exposures)));
        table_->setItem(r, column, item);
      };
      put_flip(kFlip, std::nullopt);
      put_flip(kRoiFlip, in.roi);
    }
    {
      const auto it = row.image && row.previous ? temporal_.find({row.image.get(), row.previous.get()}) : temporal_.end();
      const bool known = it != temporal_.end();
      auto* item = new NumberItem(known ? number(it->second.value, 4) : QString(row.previous && temporal_on ? "..." : "-"),
                                  known ? it->second.value : kUnknown);
      if (!row.previous) item->setToolTip(tr("No result with these settings on frame t-1"));
      table_->setItem(r, kTemporal, item);
    }
    table_->setItem(r, kTime, new NumberItem(row.seconds > 0 ? QString::number(row.seconds, 'f', 2) + " s" : "-",
                                             row.seconds > 0 ? row.seconds : kUnknown));
    if (row.a) a_row = r;
  }
  for (int c : {kRoiRelMse, kRoiSsim, kRoiFlip, kRoiPsnr}) table_->setColumnHidden(c, !in.roi);
  table_->setColumnHidden(kTemporal, !temporal_on);
  table_->setSortingEnabled(true);
  table_->sortByColumn(sort_column, sort_order);
  numberRows();
  table_->resizeColumnToContents(kName);
  table_->setColumnWidth(kName, std::clamp(table_->columnWidth(kName), 120, 260));
  // A stays selected, wherever the sort put it.
  table_->clearSelection();
  for (int r = 0; r < table_->rowCount(); ++r)
    if (a_row >= 0 && table_->item(r, kAB)->text() == "A") table_->selectRow(r);
  updating_ = false;

  QString counts = tr("Non-finite values: noisy %1 NaN, %2 Inf; reference %3 NaN, %4 Inf")
                       .arg(in.noisy_nan).arg(in.noisy_inf).arg(in.reference_nan).arg(in.reference_inf);
  counts_->setText(counts);
}

}  // namespace residue::ui
