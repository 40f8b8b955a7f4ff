#include "ui/heatmap_panel.h"

#include "core/metrics/flip.h"

#include "ui/export_all.h"
#include "ui/histogram.h"

#include <QCheckBox>
#include <QComboBox>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QPainter>
#include <QVBoxLayout>
#include <cmath>

namespace residue::ui {

namespace {
constexpr int kTemporalKind = 100;  // the kind box's item for the temporal map (not a metrics::MapKind)
constexpr int kFlipKind = 101;      // HDR-FLIP's map
}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// ColorBar

ColorBar::ColorBar(QWidget* parent) : QWidget(parent) {
  setObjectName("colorBar");
  setMinimumHeight(44);
}

void ColorBar::setScale(Colormap map, double lo, double hi, bool log, QString title) {
  map_ = map;
  lo_ = lo;
  hi_ = hi;
  log_ = log;
  title_ = std::move(title);
  update();
}

namespace {
QString tick(double v) { return QString::number(v, 'g', 3); }
}  // namespace

void paint_color_bar(QPainter& p, QRect area, Colormap map, double lo, double hi, bool log, const QString& title,
                     const QColor& text) {
  const QFontMetrics fm = p.fontMetrics();
  const int th = fm.height();
  const QRect bar(area.left() + 4, area.top() + th + 2, area.width() - 8, std::max(6, area.height() - 2 * th - 6));
  for (int x = 0; x < bar.width(); ++x) {
    const auto c = colormap_lookup(map, bar.width() > 1 ? x / static_cast<double>(bar.width() - 1) : 0.0);
    p.setPen(QColor(c[0], c[1], c[2]));
    p.drawLine(bar.left() + x, bar.top(), bar.left() + x, bar.bottom());
  }
  p.setPen(text);
  p.drawText(QRect(area.left() + 4, area.top(), area.width() - 8, th), Qt::AlignLeft | Qt::AlignVCenter, title);
  // Ticks at the ends and in the middle of the (linear or log) scale.
  const double mid = log ? std::sqrt(lo * hi) : 0.5 * (lo + hi);
  const int ty = bar.bottom() + 2;
  p.drawText(QRect(bar.left(), ty, bar.width() / 3, th), Qt::AlignLeft, tick(lo));
  p.drawText(QRect(bar.left() + bar.width() / 3, ty, bar.width() / 3, th), Qt::AlignHCenter, tick(mid));
  p.drawText(QRect(bar.left() + 2 * bar.width() / 3, ty, bar.width() - 2 * bar.width() / 3, th), Qt::AlignRight,
             tick(hi));
}

void ColorBar::paintEvent(QPaintEvent*) {
  QPainter p(this);
  paint_color_bar(p, rect(), map_, lo_, hi_, log_, title_, palette().color(QPalette::WindowText));
}

// ---------------------------------------------------------------------------------------------------------------

QImage colorize(const Image& map, Colormap colormap, const ColorScale& scale) {
  const Image rgb = apply_colormap(map, colormap, scale);  // values k / 255
  QImage img(static_cast<int>(rgb.width()), static_cast<int>(rgb.height()), QImage::Format_RGB32);
  for (int64_t y = 0; y < rgb.height(); ++y) {
    auto* line = reinterpret_cast<QRgb*>(img.scanLine(static_cast<int>(y)));
    for (int64_t x = 0; x < rgb.width(); ++x) {
      const auto byte = [&](int c) { return static_cast<int>(std::lround(rgb.at(x, y, c) * 255.0f)); };
      line[x] = qRgb(byte(0), byte(1), byte(2));
    }
  }
  return img;
}

HeatmapPanel::HeatmapPanel(QWidget* parent) : QWidget(parent) {
  auto* layout = new QVBoxLayout(this);
  auto* form = new QFormLayout;
  kind_ = new QComboBox(this);
  kind_->setObjectName("heatmapKind");
  kind_->addItem(tr("relative squared error"), static_cast<int>(metrics::MapKind::RelativeSquaredError));
  kind_->addItem(tr("absolute error"), static_cast<int>(metrics::MapKind::AbsoluteError));
  kind_->addItem(tr("squared error"), static_cast<int>(metrics::MapKind::SquaredError));
  kind_->addItem(tr("SSIM"), static_cast<int>(metrics::MapKind::Ssim));
  kind_->addItem(tr("signed difference (blue darker, red brighter)"), static_cast<int>(metrics::MapKind::SignedDifference));
  kind_->addItem(tr("HDR-FLIP"), kFlipKind);
  kind_->setItemData(kind_->count() - 1,
                     tr("NVIDIA's FLIP error: what a viewer notices when flipping between the images, over the "
                        "reference's exposures (0 to 1)"),
                     Qt::ToolTipRole);
  kind_->addItem(tr("temporal error (along the motion)"), kTemporalKind);
  kind_->setItemData(kind_->count() - 1,
                     tr("How much the error changed since frame t-1 on the same surfaces (frames of a sequence with "
                        "motion vectors; needs the result on frame t-1)"),
                     Qt::ToolTipRole);
  form->addRow(tr("Map"), kind_);
  of_ = new QComboBox(this);
  of_->setObjectName("heatmapOf");
  of_->addItem(tr("A (the denoised pane)"), static_cast<int>(Of::A));
  of_->addItem(tr("B"), static_cast<int>(Of::B));
  of_->addItem(tr("the noisy input"), static_cast<int>(Of::Noisy));
  of_->addItem(tr("A against B (B as the reference)"), static_cast<int>(Of::AgainstB));
  form->addRow(tr("Of"), of_);
  display_ = new QComboBox(this);
  display_->setObjectName("heatmapDisplay");
  display_->addItems({tr("own pane"), tr("overlay"), tr("off")});
  form->addRow(tr("Show as"), display_);
  colormap_ = new QComboBox(this);
  colormap_->setObjectName("heatmapColormap");
  for (auto m : {Colormap::Viridis, Colormap::Inferno, Colormap::Magma, Colormap::Turbo, Colormap::BlueRed})
    colormap_->addItem(QString::fromLatin1(to_string(m)), static_cast<int>(m));
  form->addRow(tr("Colormap"), colormap_);
  range_mode_ = new QComboBox(this);
  range_mode_->setObjectName("heatmapRangeMode");
  range_mode_->addItem(tr("the same for every result"));
  range_mode_->addItem(tr("this map's own"));
  range_mode_->setToolTip(tr("The same fixed range for every result, so that their maps compare by eye; or each "
                             "map's own smallest and largest values. A typed bound overrides either."));
  form->addRow(tr("Range"), range_mode_);
  log_ = new QCheckBox(tr("log scale"), this);
  log_->setObjectName("heatmapLog");
  log_->setChecked(true);
  form->addRow(QString(), log_);
  lo_ = new QLineEdit(this);
  lo_->setObjectName("heatmapLo");
  lo_->setPlaceholderText(tr("auto"));
  hi_ = new QLineEdit(this);
  hi_->setObjectName("heatmapHi");
  hi_->setPlaceholderText(tr("auto"));
  auto* bounds = new QHBoxLayout;
  bounds->addWidget(lo_);
  bounds->addWidget(new QLabel(tr("to"), this));
  bounds->addWidget(hi_);
  form->addRow(tr("Typed range"), bounds);
  layout->addLayout(form);
  bar_ = new ColorBar(this);
  layout->addWidget(bar_);
  histogram_ = new Histogram(this);
  layout->addWidget(histogram_, 1);

  connect(kind_, &QComboBox::currentIndexChanged, this, [this] {
    // SSIM lives in [-1, 1] and FLIP in [0, 1]: they read best on a linear scale; errors span decades. FLIP is
    // shown in magma, as NVIDIA's tool shows it.
    // A signed difference: linear, symmetric about 0, in the diverging map; leaving it leaves the diverging map too.
    const bool signed_map = kind() == metrics::MapKind::SignedDifference;
    log_->setChecked(kind() != metrics::MapKind::Ssim && !signed_map);
    log_->setEnabled(!signed_map);
    if (flip()) colormap_->setCurrentIndex(colormap_->findData(static_cast<int>(Colormap::Magma)));
    else if (signed_map) colormap_->setCurrentIndex(colormap_->findData(static_cast<int>(Colormap::BlueRed)));
    else if (colormap() == Colormap::BlueRed) colormap_->setCurrentIndex(colormap_->findData(static_cast<int>(Colormap::Viridis)));
    emit settingsChanged();
  });
  connect(of_, &QComboBox::currentIndexChanged, this, &HeatmapPanel::settingsChanged);
  connect(display_, &QComboBox::currentIndexChanged, this, &HeatmapPanel::displayChanged);
  connect(colormap_, &QComboBox::currentIndexChanged, this, &HeatmapPanel::recolor);
  connect(log_, &QCheckBox::toggled, this, &HeatmapPanel::recolor);
  connect(range_mode_, &QComboBox::currentIndexChanged, this, &HeatmapPanel::recolor);
  connect(lo_, &QLineEdit::editingFinished, this, &HeatmapPanel::recolor);
  connect(hi_, &QLineEdit::editingFinished, this, &HeatmapPanel::recolor);

  task_ = std::make_unique<LatestTask<Result>>(this, [this](Result&& r) {
    if (!r.error.isEmpty()) {
      bar_->setScale(colormap(), 0, 1, false, r.error);
      return;
    }
    map_ = std::move(r.map);
    image_ = std::move(r.image);
    range_ = r.range;
    subject_ = r.subject;
    bar_->setScale(colormap(), range_.first, range_.second, scale().log, title());
    histogram_->setValues(map_, scale().log, range_, colormap(), tr("Histogram of the map's values"));
    emit ready();
  });
}

HeatmapPanel::~HeatmapPanel() = default;

HeatmapPanel::Display HeatmapPanel::display() const {
  switch (display_->currentIndex()) {
    case 0: return Display::Pane;
    case 1: return Display::Overlay;
    default: return Display::Off;
  }
}
HeatmapPanel::Of HeatmapPanel::of() const { return static_cast<Of>(of_->currentData().toInt()); }
metrics::MapKind HeatmapPanel::kind() const {
  if (temporal()) return metrics::MapKind::RelativeSquaredError;
  if (flip()) return metrics::MapKind::Ssim;
  return static_cast<metrics::MapKind>(kind_->currentData().toInt());
}
bool HeatmapPanel::temporal() const { return kind_->currentData().toInt() == kTemporalKind; }
bool HeatmapPanel::flip() const { return kind_->currentData().toInt() == kFlipKind; }

std::function<Image(const Image&, const Image&)> HeatmapPanel::mapMaker(const metrics::Options& options) const {
  metrics::Options o = options;
  o.roi.reset();  // the map covers the whole image; the ROI only scopes the scores
  if (flip()) return [](const Image& test, const Image& against) { return metrics::hdr_flip(test, against).map; };
  const auto k = kind();
  return [k, o](const Image& test, const Image& against) { return metrics::error_map(test, against, k, o); };
}
Colormap HeatmapPanel::colormap() const { return static_cast<Colormap>(colormap_->currentData().toInt()); }

std::pair<double, double> HeatmapPanel::sharedRange(metrics::MapKind kind) {
  // Wide enough for a noisy input's errors, fine enough to tell two good denoisers apart at a glance.
  switch (kind) {
    case metrics::MapKind::RelativeSquaredError: return {1e-5, 1.0};
    case metrics::MapKind::AbsoluteError: return {1e-3, 1.0};
    case metrics::MapKind::SquaredError: return {1e-7, 1.0};
    case metrics::MapKind::Ssim: return {0.0, 1.0};
    case metrics::MapKind::SignedDifference: return {-0.1, 0.1};
  }
  return {0.0, 1.0};
}

bool HeatmapPanel::sharedScale() const { return range_mode_->currentIndex() == 0; }
void HeatmapPanel::setSharedScale(bool shared) { range_mode_->setCurrentIndex(shared ? 0 : 1); }

ColorScale HeatmapPanel::scale() const {
  ColorScale s;
  s.symmetric = kind() == metrics::MapKind::SignedDifference && !temporal() && !flip();
  s.log = log_->isChecked() && !s.symmetric;
  if (sharedScale()) {
    auto [lo, hi] = sharedRange(kind());
    if (s.log && lo <= 0) lo = 1e-4;  // SSIM shown on a log scale
    s.lo = lo;
    s.hi = hi;
  }
  bool ok = false;
  const double lo = lo_->text().toDouble(&ok);
  if (ok) s.lo = lo;
  const double hi = hi_->text().toDouble(&ok);
  if (ok) s.hi = hi;
  return s;
}

QString HeatmapPanel::placeholder() const {
  if (map_) return {};
  return tr("%1\n(%2)").arg(title(), missing_.isEmpty() ? tr("computing...") : missing_);
}

QString HeatmapPanel::title() const {
  // Words, not the CLI's short names ("rse" meant nothing to a first-time user).
  QString what;
  if (temporal()) {
    return tr("Temporal error along the motion of %1%2").arg(subject_.isEmpty() ? tr("nothing yet") : subject_,
                                                             scale().log ? tr(" (log)") : QString());
  }
  if (flip())
    return tr("HDR-FLIP of %1%2").arg(subject_.isEmpty() ? tr("nothing yet") : subject_, scale().log ? tr(" (log)") : QString());
  switch (kind()) {
    case metrics::MapKind::AbsoluteError: what = tr("Absolute error"); break;
    case metrics::MapKind::SquaredError: what = tr("Squared error"); break;
    case metrics::MapKind::RelativeSquaredError: what = tr("Relative squared error"); break;
    case metrics::MapKind::Ssim: what = tr("SSIM"); break;
    case metrics::MapKind::SignedDifference: what = tr("Signed difference"); break;
  }
  return tr("%1 of %2%3").arg(what, subject_.isEmpty() ? tr("nothing yet") : subject_,
                              scale().log ? tr(" (log)") : QString());
}

QImage HeatmapPanel::imageWithBar() const {
  return map_with_color_bar(image_, colormap(), range_, scale().log, title());
}

bool HeatmapPanel::busy() const { return task_->busy(); }

void HeatmapPanel::setKind(metrics::MapKind k) { kind_->setCurrentIndex(kind_->findData(static_cast<int>(k))); }
void HeatmapPanel::setTemporal() { kind_->setCurrentIndex(kind_->findData(kTemporalKind)); }
void HeatmapPanel::setFlip() { kind_->setCurrentIndex(kind_->findData(kFlipKind)); }
void HeatmapPanel::setOf(Of o) { of_->setCurrentIndex(of_->findData(static_cast<int>(o))); }
void HeatmapPanel::setDisplay(Display d) { display_->setCurrentIndex(d == Display::Pane ? 0 : d == Display::Overlay ? 1 : 2); }
void HeatmapPanel::setColormap(Colormap m) { colormap_->setCurrentIndex(colormap_->findData(static_cast<int>(m))); }
void HeatmapPanel::setLog(bool log) { log_->setChecked(log); }
void HeatmapPanel::setRange(std::optional<double> lo, std::optional<double> hi) {
  lo_->setText(lo ? QString::number(*lo, 'g', 17) : QString());
  hi_->setText(hi ? QString::number(*hi, 'g', 17) : QString());
  recolor();
}

void HeatmapPanel::compute(std::shared_ptr<const Image> test, std::shared_ptr<const Image> against,
                           const QString& subject, const QString& missing, const metrics::Options& options) {
  if (!test || !against) return computeMap(nullptr, subject, missing);
  const auto make = mapMaker(options);
  computeMap([=] { return make(*test, *against); }, subject, missing);
}

void HeatmapPanel::computeMap(std::function<Image()> make, const QString& subject, const QString& missing) {
  if (!make) {
    task_->supersede();
    map_.reset();
    image_ = QImage();
    subject_ = subject;
    missing_ = missing;
    bar_->setScale(colormap(), 0, 1, false, missing);
    histogram_->setValues(nullptr, false, {0, 1}, colormap(), missing);
    emit ready();
    return;
  }
  missing_.clear();
  const auto cm = colormap();
  const auto sc = scale();
  task_->start([=](const LatestTask<Result>::Token& token) {
    Result r;
    try {
      r.subject = subject;
      auto map = std::make_shared<Image>(make());
      if (token.superseded()) return r;  // dropped anyway: skip the colouring
      r.range = resolve_range(*map, sc);
      r.image = colorize(*map, cm, sc);
      r.map = std::move(map);
    } catch (const std::exception& e) {
      r.error = QString::fromStdString(e.what());
    }
    return r;
  });
}

void HeatmapPanel::recolor() {
  if (!map_) {
    emit settingsChanged();
    return;
  }
  const auto sc = scale();
  try {
    resolve_range(*map_, sc);  // checks the typed range at once, so a bad one is flagged where it was typed
    lo_->setStyleSheet(QString());
    hi_->setStyleSheet(QString());
  } catch (const std::exception& e) {
    lo_->setStyleSheet("background: #702020");
    hi_->setStyleSheet("background: #702020");
    bar_->setScale(colormap(), 0, 1, false, QString::fromStdString(e.what()));
    return;
  }
  // Colouring a large map takes a moment: off the UI thread too.
  const auto map = map_;
  const auto cm = colormap();
  const QString subject = subject_;
  task_->start([=](const LatestTask<Result>::Token&) {
    Result r;
    r.subject = subject;
    r.range = resolve_range(*map, sc);
    r.image = colorize(*map, cm, sc);
    r.map = map;
    return r;
  });
}

}  // namespace residue::ui
