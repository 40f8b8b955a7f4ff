#include "ui/session.h"

#include <QtConcurrent/QtConcurrentRun>
#include <algorithm>

#include "core/denoise/strength.h"
#include "core/util/error.h"

namespace residue::ui {

const char* to_string(Source s) {
  switch (s) {
    case Source::Noisy: return "Noisy";
    case Source::Denoised: return "Denoised";
    case Source::Reference: return "Reference";
    case Source::Heatmap: return "Heatmap";
  }
  return "?";
}

QString display_name(AovRole role) {
  QString name = QString::fromLatin1(to_string(role));  // "color", "albedo", ...
  if (role == AovRole::Color) name = QStringLiteral("colour");
  name[0] = name[0].toUpper();
  return name;
}

struct Session::LoadResult {
  int generation = 0;
  bool reference_only = false;
  std::vector<std::filesystem::path> inputs;
  LoadOptions options;
  std::shared_ptr<AovStack> stack;
  QString error;
  int error_kind = -1;
};

Session::Session(QObject* parent) : QObject(parent) {
  qRegisterMetaType<residue::Rect>("residue::Rect");
  watcher_ = new QFutureWatcher<std::shared_ptr<LoadResult>>(this);
  connect(watcher_, &QFutureWatcherBase::finished, this, &Session::finishLoad);
}

Session::~Session() { watcher_->waitForFinished(); }

void Session::open(const std::vector<std::filesystem::path>& inputs, const LoadOptions& options) {
  startLoad(inputs, options, false);
}

void Session::openReference(const std::filesystem::path& file) {
  if (!stack_) return;
  LoadOptions o = options_;
  o.reference = file;
  startLoad(inputs_, o, true);
}

void Session::reload() {
  if (!inputs_.empty()) startLoad(inputs_, options_, false);
}

void Session::startLoad(std::vector<std::filesystem::path> inputs, LoadOptions options, bool reference_only) {
  const int generation = ++generation_;
  loading_ = true;
  QStringList names;
  for (const auto& p : inputs) names << QString::fromStdString(p.filename().string());
  emit loadStarted(reference_only && options.reference
                       ? QString::fromStdString(options.reference->filename().string())
                       : names.join(", "));
  // A superseded load still runs to its end (OpenImageIO reads cannot be interrupted); its result is dropped.
  watcher_->setFuture(QtConcurrent::run([=]() {
    auto r = std::make_shared<LoadResult>();
    r->generation = generation;
    r->reference_only = reference_only;
    r->inputs = inputs;
    r->options = options;
    try {
      r->stack = std::make_shared<AovStack>(load_aov_stack(inputs, options));
    } catch (const Error& e) {
      r->error = QString::fromStdString(e.what());
      r->error_kind = static_cast<int>(e.kind());
    } catch (const std::exception& e) {
      r->error = QString::fromStdString(e.what());
    }
    return r;
  }));
}

void Session::finishLoad() {
  const auto r = watcher_->result();
  if (!r || r->generation != generation_) return;
  loading_ = false;
  if (!r->stack) {
    QStringList names;
    for (const auto& p : r->inputs) names << QString::fromStdString(p.string());
    emit loadFailed(r->error, r->error_kind, names);
    return;
  }
  const bool same_grid = stack_ && stack_->width() == r->stack->width() && stack_->height() == r->stack->height();
  inputs_ = r->inputs;
  live_name_.clear();
  options_ = r->options;
  stack_ = r->stack;
  if (r->reference_only && same_grid) {
    emit referenceChanged();
    return;
  }
  denoised_.reset();
  blended_.reset();
  denoised_description_.clear();
  emit loaded();
}

void Session::adoptLive(std::shared_ptr<const AovStack> stack, const QString& name) {
  ++generation_;  // a file load still in flight is dropped when it ends
  loading_ = false;
  inputs_.clear();
  live_name_ = name;
  stack_ = std::move(stack);
  denoised_.reset();
  blended_.reset();
  denoised_description_.clear();
  emit loaded();
}

QString Session::title() const {
  if (!live_name_.isEmpty()) return tr("%1 (live)").arg(live_name_);
  QStringList names;
  for (const auto& p : inputs_) {
    // A folder given as "dir/" has an empty file name: name the folder itself.
    const auto name = p.has_filename() ? p.filename() : p.parent_path().filename();
    names << QString::fromStdString(name.string());
  }
  return names.join(", ");
}

const Image* Session::reference() const {
  return stack_ && stack_->reference ? &stack_->reference->image : nullptr;
}

bool Session::hasAov(AovRole role) const { return image(Source::Noisy, role) != nullptr; }

const Image* Session::image(Source s, AovRole aov) const {
  if (!stack_) return nullptr;
  switch (s) {
    case Source::Noisy: {
      const Aov* a = stack_->find(aov);
      return a ? &a->image : nullptr;
    }
    case Source::Denoised: return denoised();
    case Source::Reference: return reference();
    case Source::Heatmap: return nullptr;
  }
  return nullptr;
}

void Session::beginDenoised() {
  if (!stack_) return;
  const Image& noisy = stack_->color.image;
  // The noisy colour's first three channels, so tiles that have not run yet show the input.
  auto img = std::make_shared<Image>(noisy.width(), noisy.height(), 3);
  if (noisy.channels() == 3) {
    std::copy(noisy.data(), noisy.data() + noisy.size(), img->data());
  } else {
    for (int64_t y = 0; y < noisy.height(); ++y)
      for (int64_t x = 0; x < noisy.width(); ++x)
        for (int c = 0; c < 3; ++c) img->at(x, y, c) = noisy.at(x, y, c);
  }
  denoised_ = std::move(img);
  denoised_description_.clear();
  reblend();
  emit denoisedChanged();
}

void Session::setDenoisedTile(const Rect& rect, const Image& pixels) {
  if (!denoised_ || !denoised_->bounds().contains(rect)) return;
  // Copy on write: a worker (metrics, heatmap, export) may hold the previous image; it keeps its snapshot.
  if (denoised_.use_count() > 1) denoised_ = std::make_shared<Image>(*denoised_);
  for (int64_t y = 0; y < rect.height; ++y)
    for (int64_t x = 0; x < rect.width; ++x)
      for (int c = 0; c < 3; ++c) denoised_->at(rect.x + x, rect.y + y, c) = pixels.at(x, y, c);
  reblend(rect);
  emit denoisedTileChanged(rect);
}

void Session::adoptDenoised(std::shared_ptr<Image> image, QString description) {
  denoised_ = std::move(image);
  denoised_description_ = std::move(description);
  reblend();
  emit denoisedChanged();
}

void Session::clearDenoised() {
  denoised_.reset();
  blended_.reset();
  denoised_description_.clear();
  emit denoisedChanged();
}

void Session::setStrength(float strength) {
  check_strength(strength);
  if (strength == strength_) return;
  strength_ = strength;
  reblend();
  emit denoisedChanged();
}

QString Session::denoisedDescription() const {
  if (strength_ >= 1.0f || denoised_description_.isEmpty()) return denoised_description_;
  return denoised_description_ + QString(", strength %1").arg(static_cast<double>(strength_), 0, 'f', 2);
}

// Re-makes the shown image from the result at strength 1: all of it, or one rectangle (a tile just written).
void Session::reblend(const std::optional<Rect>& rect) {
  if (strength_ >= 1.0f || !denoised_ || !stack_) {
    blended_.reset();
    return;
  }
  const Image& noisy = stack_->color.image;
  if (!rect || !blended_) {
    blended_ = std::make_shared<Image>(with_strength(noisy, *denoised_, strength_));
    return;
  }
  if (blended_.use_count() > 1) blended_ = std::make_shared<Image>(*blended_);  // copy on write, as above
  for (int64_t y = rect->y; y < rect->y + rect->height; ++y)
    for (int64_t x = rect->x; x < rect->x + rect->width; ++x)
      for (int c = 0; c < 3; ++c) blended_->at(x, y, c) = denoised_->at(x, y, c);
  apply_strength(noisy, 0, *blended_, 0, *rect, rect->y, rect->height, strength_);
}

}  // namespace residue::ui
