#include "ui/session.h"

#include <QScopeGuard>
#include <QTimer>
#include <QtConcurrent/QtConcurrentRun>
#include <algorithm>

#include "core/denoise/strength.h"
#include "core/util/error.h"

namespace residue::ui {

const char* to_string(Source s) {
  switch (s) {
    case Source::Noisy: return "Noisy";
    case Source::Denoised: return "Denoised";
    case Source::Compare: return "Compare";
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
  bool reload = false;  // the shown render read again, in place
  bool focus = true;    // a new render is shown (else it joins the list unshown)
  bool step = false;  // another frame of the sequence shown (showFrame), not a new render
  std::vector<std::filesystem::path> inputs;
  LoadOptions options;
  std::shared_ptr<AovStack> stack;
  std::optional<FrameSequence> sequence;  // the sequence the render is a frame of
  int64_t frame = 0;
  std::map<int64_t, std::shared_ptr<const AovStack>> nearby;  // frames t-1 and t+1
  QString error;
  int error_kind = -1;
};

namespace {

// What a result is across the frames of a sequence: the settings of a run, or a numbered file's pattern.
QString series(const Result& r) {
  if (!r.fromFile()) return "run:" + r.key;
  if (const auto p = io::FramePattern::of_numbered_file(r.file.toStdString()))
    return QString::fromStdString("file:" + p->to_string());
  return "file:" + r.file;
}

// A render's name in the list and the window title: the stream's, or its files' (a folder given as "dir/" has an
// empty file name: the folder itself is named).
QString render_title(const std::vector<std::filesystem::path>& inputs, const QString& live_name) {
  if (!live_name.isEmpty()) return Session::tr("%1 (live)").arg(live_name);
  QStringList names;
  for (const auto& p : inputs)
    names << QString::fromStdString((p.has_filename() ? p.filename() : p.parent_path().filename()).string());
  return names.join(", ");
}

// What a result at a strength is called and keyed by, from its full result: a key of its own (never a run's, so
// asking for the run's settings shows the full result) that is also, across a shot's frames, the series of "this
// run (or file) at this strength".
void describe_at_strength(Result& r, const Result& base, float strength) {
  const auto s = static_cast<double>(strength);
  r.base = base.id;
  r.strength = strength;
  r.name = base.name + QString(" @ %1 %").arg(s * 100.0, 0, 'f', 0);
  r.key = (base.fromFile() ? "file:" + base.file : base.key) + QString("@strength %1").arg(s, 0, 'f', 2);
  r.description = base.description + QString(", strength %1").arg(s, 0, 'f', 2);
}

}  // namespace

Session::Session(QObject* parent) : QObject(parent) {
  qRegisterMetaType<residue::Rect>("residue::Rect");
  watcher_ = new QFutureWatcher<std::shared_ptr<LoadResult>>(this);
  connect(watcher_, &QFutureWatcherBase::finished, this, &Session::finishLoad);
}

Session::~Session() { watcher_->waitForFinished(); }

void Session::open(const std::vector<std::filesystem::path>& inputs, const LoadOptions& options, bool focus) {
  if (const int open = findRender(inputs, {}); open >= 0) {
    if (focus) showRender(open);
    return;
  }
  if (loading_ && load_is_new_) return queued_.push_back({inputs, options, focus});
  startLoad(inputs, options, false, std::nullopt, false, focus);
}

void Session::startQueued() {
  if (loading_ || queued_.empty()) return;
  QueuedOpen next = std::move(queued_.front());
  queued_.pop_front();
  open(next.inputs, next.options, next.focus);
}

void Session::closeLive(const QString& name) {
  if (const int i = findRender({}, name); i >= 0) closeRender(i);
}

void Session::openReference(const std::filesystem::path& file) {
  if (!stack_) return;
  LoadOptions o = options_;
  o.reference = file;
  startLoad(inputs_, o, true);
}

void Session::reload() {
  if (!inputs_.empty()) startLoad(inputs_, options_, false, std::nullopt, true);
}

bool Session::showFrame(int64_t frame) {
  if (!sequence_ || !sequence_->contains(frame) || !stack_) return false;
  LoadOptions o = options_;
  o.reference = sequence_->referenceFor(frame);
  startLoad({sequence_->input(frame)}, o, false, frame);
  return true;
}

std::shared_ptr<const AovStack> Session::frameStack(int64_t frame) const {
  if (!sequence_) return nullptr;
  if (frame == frame_) return stack_;
  const auto it = nearby_.find(frame);
  return it == nearby_.end() ? nullptr : it->second;
}

std::shared_ptr<const Image> Session::previousImage(const Result* r) const {
  if (!sequence_) return nullptr;
  if (!r) {
    const auto prev = frameStack(frame_ - 1);
    return prev ? std::shared_ptr<const Image>(prev, &prev->color.image) : nullptr;
  }
  const auto it = memories_.find(frame_ - 1);
  if (it == memories_.end()) return nullptr;
  const QString want = series(*r);
  for (const Result& p : it->second.results)
    if (p.image && p.complete && p.done() && series(p) == want) return p.image;
  return nullptr;
}

void Session::startLoad(std::vector<std::filesystem::path> inputs, LoadOptions options, bool reference_only,
                        std::optional<int64_t> frame, bool reload, bool focus) {
  const int generation = ++generation_;
  loading_ = true;
  load_is_new_ = !reference_only && !frame && !reload;
  QStringList names;
  for (const auto& p : inputs) names << QString::fromStdString(p.filename().string());
  emit loadStarted(reference_only && options.reference
                       ? QString::fromStdString(options.reference->filename().string())
                       : names.join(", "));
  // Frames a step can reuse instead of reading them again (not after another reference: theirs may change too).
  std::map<int64_t, std::shared_ptr<const AovStack>> held;
  if (frame && sequence_ && !reference_only) {
    held = nearby_;
    held[frame_] = stack_;
  }
  const std::optional<FrameSequence> known = frame ? sequence_ : std::nullopt;
  const bool in_sequence = sequence_.has_value();
  // A superseded load still runs to its end (OpenImageIO reads cannot be interrupted); its result is dropped.
  watcher_->setFuture(QtConcurrent::run([=]() {
    auto r = std::make_shared<LoadResult>();
    r->generation = generation;
    r->reference_only = reference_only;
    r->reload = reload;
    r->focus = focus;
    r->step = frame.has_value();
    r->inputs = inputs;
    r->options = options;
    try {
      // A new render finds its sequence; a reference opened for a frame of one may be a pattern for all of them.
      if (known) {
        r->sequence = known;
        r->frame = *frame;
      } else if (inputs.size() == 1 && (!reference_only || in_sequence)) {
        r->sequence = FrameSequence::of(inputs.front(), options.reference);
        if (r->sequence) {
          r->frame = *r->sequence->pattern.frame_of(inputs.front().string());
          if (!r->options.reference) r->options.reference = r->sequence->referenceFor(r->frame);
        }
      }
      r->stack = std::make_shared<AovStack>(load_aov_stack(inputs, r->options));
      if (r->sequence)
        for (const int64_t f : {r->frame - 1, r->frame + 1}) {
          if (!r->sequence->contains(f)) continue;
          if (const auto it = held.find(f); it != held.end() && it->second) {
            r->nearby[f] = it->second;
            continue;
          }
          LoadOptions o = r->options;
          o.reference = r->sequence->referenceFor(f);
          try {
            r->nearby[f] = std::make_shared<AovStack>(load_aov_stack({r->sequence->input(f)}, o));
          } catch (const std::exception&) {
            // a neighbour that cannot be read is one the frame does without
          }
        }
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
  load_is_new_ = false;
  // A render asked for meanwhile is opened next, whatever this load's end.
  const auto next = qScopeGuard([this] { startQueued(); });
  if (!r->stack) {
    QStringList names;
    for (const auto& p : r->inputs) names << QString::fromStdString(p.string());
    emit loadFailed(r->error, r->error_kind, names);
    return;
  }
  const bool same_grid = stack_ && stack_->width() == r->stack->width() && stack_->height() == r->stack->height();
  // A new render joins the end of the list (as in tev), and the one shown keeps everything; a reload, another
  // frame or another reference stays in the shown render's entry.
  if (!r->reload && !r->step && !r->reference_only) {
    if (!r->focus && current_ >= 0) {
      Render& unshown = newEntry();
      unshown.stack = r->stack;
      unshown.inputs = r->inputs;
      unshown.options = r->options;
      unshown.sequence = r->sequence;
      unshown.frame = r->frame;
      unshown.nearby = r->nearby;
      emit renderListChanged();
      return;
    }
    if (current_ >= 0) emit aboutToSwitch();
    showNewEntry();
  }
  inputs_ = r->inputs;
  live_name_.clear();
  options_ = r->options;
  if (r->step && sequence_) {
    enterFrame(*r);
    emit loaded();
    emit frameChanged();
    return;
  }
  stack_ = r->stack;
  if (r->reference_only && same_grid) {
    if (sequence_ && r->sequence) sequence_->reference = r->sequence->reference;
    nearby_ = r->nearby;
    emit referenceChanged();
    return;
  }
  clearResults();
  sequence_ = r->sequence;
  frame_ = r->frame;
  nearby_ = r->nearby;
  emit loaded();
  emit renderListChanged();
}

void Session::enterFrame(const LoadResult& r) {
  // The frame shown keeps its results; the one coming back gets its own, if it was shown before.
  const Result* old_a = result(a_);
  const Result* old_b = result(b_);
  const QString want_a = old_a ? series(*old_a) : QString(), want_b = old_b ? series(*old_b) : QString();
  // A at a strength: on a frame that has its full result but not at that strength, it is made there.
  const Result* old_a_base = old_a && old_a->atStrength() ? result(old_a->base) : nullptr;
  const QString want_a_base = old_a_base ? series(*old_a_base) : QString();
  const float a_strength = old_a ? old_a->strength : 1.0f;
  std::vector<std::pair<QString, QString>> files;  // files added on the frame shown, with their series
  for (const Result& x : results_)
    if (x.fromFile()) files.emplace_back(x.file, series(x));
  const int64_t left = frame_;
  memories_[frame_] = FrameMemory{std::move(results_), a_, b_};
  results_.clear();
  a_ = b_ = -1;
  frame_ = r.frame;
  stack_ = r.stack;
  nearby_ = r.nearby;
  if (const auto it = memories_.find(frame_); it != memories_.end()) {
    results_ = std::move(it->second.results);
    a_ = it->second.a;
    b_ = it->second.b;
    memories_.erase(it);
  }
  ++results_epoch_;
  // A and B show the same settings (or file series) as on the frame before, where this frame has them.
  for (const Result& x : results_) {
    if (!want_a.isEmpty() && series(x) == want_a) a_ = x.id;
    if (!want_b.isEmpty() && series(x) == want_b && x.id != a_) b_ = x.id;
  }
  if (!want_a_base.isEmpty() && (a_ < 0 || series(*result(a_)) != want_a))
    for (const Result& x : results_)
      if (series(x) == want_a_base) {
        a_ = deriveAtStrength(x.id, a_strength);
        break;
      }
  follow_a_ = want_a;
  follow_b_ = want_b;
  // A numbered file added on the frame before brings its own file of this frame (at the same frame offset).
  for (const auto& [f, name] : files) {
    const auto p = io::FramePattern::of_numbered_file(f.toStdString());
    const auto n = p ? p->frame_of(f.toStdString()) : std::nullopt;
    if (!n) continue;
    const std::filesystem::path here = p->path(frame_ + (*n - left));
    std::error_code ec;
    const bool has = std::any_of(results_.begin(), results_.end(), [&](const Result& x) { return series(x) == name; });
    if (!has && std::filesystem::is_regular_file(here, ec)) addResultFile(here);
  }
}

void Session::adoptLive(std::shared_ptr<const AovStack> stack, const QString& name, bool focus) {
  const int i = findRender({}, name);
  if (i != current_ || current_ < 0) {
    if (!focus && current_ >= 0) {  // into its entry (a new one at the end of the list), unshown
      Render* r = nullptr;
      if (i >= 0) {
        r = &renders_[static_cast<size_t>(i)];
      } else {
        r = &newEntry();
        r->live_name = name;
      }
      r->stack = std::move(stack);
      r->results.clear();  // they were of the pixels before
      r->memories.clear();
      r->a = r->b = -1;
      ++r->epoch;
      emit renderListChanged();
      return;
    }
    if (current_ >= 0) emit aboutToSwitch();
    if (i >= 0) switchTo(i);
    else showNewEntry();
  }
  dropLoadOfShown();
  inputs_.clear();
  live_name_ = name;
  stack_ = std::move(stack);
  clearResults();
  sequence_.reset();
  nearby_.clear();
  emit loaded();
  emit renderListChanged();
}

// ---------------------------------------------------------------------------------------------------------------
// The image list

Session::Render Session::stash() {
  Render r;
  r.id = current_ >= 0 ? renders_[static_cast<size_t>(current_)].id : 0;
  r.stack = std::move(stack_);
  r.inputs = std::move(inputs_);
  r.live_name = std::move(live_name_);
  r.options = std::move(options_);
  r.results = std::move(results_);
  r.a = a_;
  r.b = b_;
  r.sequence = std::move(sequence_);
  r.frame = frame_;
  r.memories = std::move(memories_);
  r.nearby = std::move(nearby_);
  r.follow_a = std::move(follow_a_);
  r.follow_b = std::move(follow_b_);
  r.epoch = results_epoch_;
  stack_.reset();
  inputs_.clear();
  live_name_.clear();
  options_ = {};
  results_.clear();
  a_ = b_ = -1;
  sequence_.reset();
  frame_ = 0;
  memories_.clear();
  nearby_.clear();
  follow_a_.clear();
  follow_b_.clear();
  return r;
}

void Session::unstash(Render&& r) {
  stack_ = std::move(r.stack);
  inputs_ = std::move(r.inputs);
  live_name_ = std::move(r.live_name);
  options_ = std::move(r.options);
  results_ = std::move(r.results);
  a_ = r.a;
  b_ = r.b;
  sequence_ = std::move(r.sequence);
  frame_ = r.frame;
  memories_ = std::move(r.memories);
  nearby_ = std::move(r.nearby);
  follow_a_ = std::move(r.follow_a);
  follow_b_ = std::move(r.follow_b);
  results_epoch_ = r.epoch;
}

Session::Render& Session::newEntry() {
  Render fresh;
  fresh.id = next_render_id_++;
  renders_.push_back(std::move(fresh));
  return renders_.back();
}

void Session::showNewEntry() {
  if (current_ >= 0) renders_[static_cast<size_t>(current_)] = stash();
  newEntry();
  current_ = renderCount() - 1;
}

void Session::switchTo(int index) {
  if (index == current_) return;
  if (current_ >= 0) renders_[static_cast<size_t>(current_)] = stash();
  current_ = index;
  const int id = renders_[static_cast<size_t>(index)].id;
  unstash(std::move(renders_[static_cast<size_t>(index)]));
  renders_[static_cast<size_t>(index)] = Render{};
  renders_[static_cast<size_t>(index)].id = id;
}

void Session::dropLoadOfShown() {
  // A reload, frame step or reference in flight was for the render shown before: dropped when it ends. A render
  // being opened is not: it joins the list.
  if (!loading_ || load_is_new_) return;
  ++generation_;
  loading_ = false;
  QTimer::singleShot(0, this, &Session::startQueued);
}

int Session::findRender(const std::vector<std::filesystem::path>& inputs, const QString& live_name) const {
  const auto same = [](const std::vector<std::filesystem::path>& a, const std::vector<std::filesystem::path>& b) {
    if (a.size() != b.size()) return false;
    for (size_t i = 0; i < a.size(); ++i) {
      std::error_code ec;
      if (!std::filesystem::equivalent(a[i], b[i], ec)) return false;
    }
    return true;
  };
  for (int i = 0; i < renderCount(); ++i) {
    const bool shown = i == current_;
    const auto& in = shown ? inputs_ : renders_[static_cast<size_t>(i)].inputs;
    const QString& live = shown ? live_name_ : renders_[static_cast<size_t>(i)].live_name;
    if (!live_name.isEmpty() ? live == live_name : (!inputs.empty() && live.isEmpty() && same(in, inputs))) return i;
  }
  return -1;
}

QString Session::renderTitle(int index) const {
  if (index == current_) return title();
  if (index < 0 || index >= renderCount()) return {};
  const Render& r = renders_[static_cast<size_t>(index)];
  return render_title(r.inputs, r.live_name);
}

QStringList Session::renderInputs(int index) const {
  if (index < 0 || index >= renderCount()) return {};
  QStringList out;
  for (const auto& p : index == current_ ? inputs_ : renders_[static_cast<size_t>(index)].inputs)
    out << QString::fromStdString(p.string());
  return out;
}

int Session::renderResultCount(int index) const {
  if (index == current_) return static_cast<int>(results_.size());
  if (index < 0 || index >= renderCount()) return 0;
  return static_cast<int>(renders_[static_cast<size_t>(index)].results.size());
}

int Session::renderId(int index) const {
  return index < 0 || index >= renderCount() ? 0 : renders_[static_cast<size_t>(index)].id;
}

void Session::showRender(int index) {
  if (index < 0 || index >= renderCount()) return;
  dropLoadOfShown();
  emit aboutToSwitch();
  switchTo(index);
  switching_ = true;
  emit loaded();
  switching_ = false;
  emit renderListChanged();
}

void Session::closeRender(int index) {
  if (index < 0 || index >= renderCount()) return;
  if (index != current_) {
    renders_.erase(renders_.begin() + index);
    if (index < current_) --current_;
    emit renderListChanged();
    return;
  }
  dropLoadOfShown();
  emit aboutToSwitch();
  stash();  // the shown one's members go with it
  renders_.erase(renders_.begin() + index);
  current_ = -1;
  if (!renders_.empty()) switchTo(std::min(index, renderCount() - 1));
  emit loaded();  // not a switch: a run for the closed render stops
  emit renderListChanged();
}

QString Session::title() const { return render_title(inputs_, live_name_); }

const Image* Session::reference() const {
  return stack_ && stack_->reference ? &stack_->reference->image : nullptr;
}

bool Session::hasAov(AovRole role) const { return image(Source::Noisy, role) != nullptr; }

const std::vector<OtherLayer>& Session::otherLayers() const {
  if (layers_of_.lock() != stack_) {
    layers_of_ = stack_;
    layer_images_.clear();
    other_layers_ = stack_ ? other_layers(*stack_) : std::vector<OtherLayer>{};
  }
  return other_layers_;
}

std::shared_ptr<const Image> Session::otherLayer(int index) const {
  const auto& layers = otherLayers();
  if (index < 0 || index >= static_cast<int>(layers.size())) return nullptr;
  auto& image = layer_images_[index];
  if (!image) image = std::make_shared<const Image>(read_other_layer(layers[static_cast<size_t>(index)], *stack_));
  return image;
}

const Image* Session::image(Source s, AovRole aov) const {
  if (!stack_) return nullptr;
  switch (s) {
    case Source::Noisy: {
      const Aov* a = stack_->find(aov);
      return a ? &a->image : nullptr;
    }
    case Source::Denoised: return denoised();
    case Source::Compare: return compareShared().get();
    case Source::Reference: return reference();
    case Source::Heatmap: return nullptr;
  }
  return nullptr;
}

// ---------------------------------------------------------------------------------------------------------------
// Results

void Session::clearResults() {
  results_.clear();
  memories_.clear();
  follow_a_.clear();
  follow_b_.clear();
  a_ = b_ = -1;
  ++results_epoch_;
}

Result* Session::find(int id) {
  if (std::vector<Result>* list = listOf(id))
    for (auto& r : *list)
      if (r.id == id) return &r;
  return nullptr;
}

std::vector<Result>* Session::listOf(int id) {
  const auto has = [id](const std::vector<Result>& l) {
    return std::any_of(l.begin(), l.end(), [id](const Result& r) { return r.id == id; });
  };
  if (has(results_)) return &results_;
  for (Render& r : renders_)
    if (has(r.results)) return &r.results;
  return nullptr;
}

const Result* Session::result(int id) const {
  for (const auto& r : results_)
    if (r.id == id) return &r;
  return nullptr;
}

bool Session::holds(int id) const { return const_cast<Session*>(this)->find(id) != nullptr; }

const Result* Session::findRun(const QString& key) const {
  for (const auto& r : results_)
    if (!r.key.isEmpty() && r.key == key) return &r;
  return nullptr;
}

QString Session::uniqueName(const QString& name, int id) const {
  // Names are unique, so that a row, a pane label and an exported file name each say which result they are.
  QString unique = name;
  for (int n = 2; std::any_of(results_.begin(), results_.end(), [&](const Result& o) { return o.id != id && o.name == unique; }); ++n)
    unique = QString("%1 (%2)").arg(name).arg(n);
  return unique;
}

int Session::addResult(Result r) {
  r.id = next_id_++;
  r.name = uniqueName(r.name, r.id);
  results_.push_back(std::move(r));
  emit resultsChanged();
  return results_.back().id;
}

void Session::setResultTile(int id, const Rect& rect, const Image& pixels) {
  Result* r = find(id);
  if (!r || !r->image || !r->image->bounds().contains(rect)) return;
  // Copy on write: a worker (metrics, heatmap, export) may hold the previous image; it keeps its snapshot.
  if (r->image.use_count() > 1) r->image = std::make_shared<Image>(*r->image);
  for (int64_t y = 0; y < rect.height; ++y)
    for (int64_t x = 0; x < rect.width; ++x)
      for (int c = 0; c < 3; ++c) r->image->at(rect.x + x, rect.y + y, c) = pixels.at(x, y, c);
  if (id == a_) emit denoisedTileChanged(rect);
  reblendFrom(id, rect);
}

void Session::updateResult(int id, const std::function<void(Result&)>& edit) {
  Result* r = find(id);
  if (!r) return;
  const Image* before = r->image.get();
  edit(*r);
  emit resultsChanged();
  if (r->image.get() != before) {
    if (id == a_) emit denoisedChanged();
    if (id == b_) emit compareChanged();
  }
  reblendFrom(id, std::nullopt, r->image.get() != before);  // its blends: their state, and their pixels if need be
}

void Session::removeResult(int id) {
  if (!result(id)) return;
  // Its blends at a strength go with it: they are it, re-blended.
  std::vector<int> derived;
  for (const Result& r : results_)
    if (r.base == id) derived.push_back(r.id);
  for (int d : derived) removeOne(d);
  removeOne(id);
  emit resultsChanged();
}

void Session::removeOne(int id) {
  const auto it = std::find_if(results_.begin(), results_.end(), [&](const Result& r) { return r.id == id; });
  if (it == results_.end()) return;
  results_.erase(it);
  if (b_ == id) {
    b_ = -1;
    emit compareChanged();
  }
  if (a_ == id) {  // B takes A's place; without a B, the newest result does
    a_ = b_ >= 0 ? b_ : results_.empty() ? -1 : results_.back().id;
    if (b_ >= 0) {
      b_ = -1;
      emit compareChanged();
    }
    emit denoisedChanged();
  }
}

void Session::setA(int id) {
  if (id >= 0 && !result(id)) return;
  if (id == b_ && id >= 0) {  // picking B as A swaps them, as a flip would
    b_ = a_;
    emit compareChanged();
  }
  a_ = id;
  emit denoisedChanged();
  emit resultsChanged();
}

void Session::setB(int id) {
  if (id >= 0 && !result(id)) return;
  if (id == a_ && id >= 0) {
    a_ = b_;
    emit denoisedChanged();
  }
  b_ = id;
  emit compareChanged();
  emit resultsChanged();
}

std::shared_ptr<const Image> Session::denoisedShared() const {
  const Result* r = result(a_);
  return r ? r->image : nullptr;
}

std::shared_ptr<const Image> Session::compareShared() const {
  const Result* r = result(b_);
  return r ? r->image : nullptr;
}

void Session::addResultFile(const std::filesystem::path& file) {
  if (!stack_) return emit resultFailed(tr("Open a render before adding results to compare with it."));
  const int64_t w = stack_->width(), h = stack_->height();
  const int epoch = results_epoch_;
  const int render = renderId(current_);
  auto* watcher = new QFutureWatcher<Result>(this);
  auto error = std::make_shared<QString>();
  connect(watcher, &QFutureWatcherBase::finished, this, [this, watcher, epoch, error, render] {
    watcher->deleteLater();
    if (!error->isEmpty()) return emit resultFailed(*error);
    // Another render is shown now: the file joins its own render's list, if that is still open and unchanged.
    if (render != renderId(current_)) {
      for (Render& x : renders_)
        if (x.id == render && x.epoch == epoch) {
          Result r = watcher->result();
          r.id = next_id_++;
          x.results.push_back(std::move(r));
          if (x.a < 0) x.a = x.results.back().id;
          emit renderListChanged();
        }
      return;
    }
    if (epoch != results_epoch_) return;  // the render changed meanwhile
    const int id = addResult(watcher->result());
    const QString s = series(*result(id));
    if (a_ < 0 || s == follow_a_) setA(id);
    else if (b_ < 0 || s == follow_b_) setB(id);
  });
  watcher->setFuture(QtConcurrent::run([file, w, h, error]() {
    Result r;
    r.file = QString::fromStdString(file.string());
    r.name = QString::fromStdString(file.filename().string());
    r.complete = true;
    try {
      LoadOptions o;
      o.load_reference = false;
      const AovStack s = load_aov_stack({file}, o);
      if (s.width() != w || s.height() != h)
        throw Error(ErrorKind::Input, file.string() + ": an image of " + std::to_string(s.width()) + " x " +
                                          std::to_string(s.height()) + " pixels cannot be compared with a render of " +
                                          std::to_string(w) + " x " + std::to_string(h));
      const Image& c = s.color.image;
      auto img = std::make_shared<Image>(w, h, 3);
      for (int64_t y = 0; y < h; ++y)
        for (int64_t x = 0; x < w; ++x)
          for (int k = 0; k < 3; ++k) img->at(x, y, k) = c.at(x, y, std::min(k, c.channels() - 1));
      r.image = std::move(img);
      r.description = r.file;
      // An EXR Residue wrote says what made it.
      if (const auto* model = s.metadata.find_pv(OIIO::ustring("residue:model")))
        r.description += " (" + QString::fromStdString(model->get_string()) + ")";
    } catch (const std::exception& e) {
      *error = QString::fromStdString(e.what());
    }
    return r;
  }));
}

void Session::setStrength(float strength) {
  check_strength(strength);
  const Result* a = result(a_);
  if (!a || a->strength == strength) return;
  const int base = a->atStrength() ? a->base : a->id;
  if (!result(base) || !result(base)->image) return;
  if (strength >= 1.0f) {  // the full result itself: the blend goes
    const int blend = a_;
    setA(base);
    removeResult(blend);
    return;
  }
  if (a->atStrength()) {  // moving the slider re-blends the result at a strength shown, in place
    const Result& b = *result(base);
    updateResult(a_, [&](Result& r) {
      describe_at_strength(r, b, strength);
      r.name = uniqueName(r.name, r.id);
    });
    reblendFrom(base);
    return;
  }
  // From a full result: a blend at this strength already kept is shown rather than made twice.
  for (const Result& r : results_)
    if (r.base == base && r.strength == strength) return setA(r.id);
  setA(deriveAtStrength(base, strength));
}

int Session::deriveAtStrength(int base, float strength) {
  const Result* b = result(base);
  Result r;
  describe_at_strength(r, *b, strength);
  r.file = b->file;
  r.provenance = b->provenance;
  r.flop = b->flop;
  const int id = addResult(std::move(r));
  reblendFrom(base);
  return id;
}

float Session::strength() const {
  const Result* a = result(a_);
  return a ? a->strength : 1.0f;
}

QString Session::denoisedDescription() const {
  const Result* r = result(a_);
  return r ? r->description : QString();
}

QString Session::resultName(int id) const {
  const Result* r = result(id);
  return r ? r->name : QString();
}

void Session::reblendFrom(int base, const std::optional<Rect>& rect, bool pixels) {
  std::vector<Result>* list = listOf(base);
  const Result* b = find(base);
  if (!list || !b || !b->image) return;
  // The noisy colour of the render the result belongs to (a run goes on while another render is shown).
  std::shared_ptr<const AovStack> stack = stack_;
  if (list != &results_)
    for (const Render& x : renders_)
      if (&x.results == list) stack = x.stack;
  if (!stack) return;
  const Image& full = *b->image;
  const Image& noisy = stack->color.image;
  for (Result& r : *list) {
    if (r.base != base) continue;
    r.complete = b->complete;
    r.rects = b->rects;
    r.state = b->state;
    r.stateText = b->stateText;
    r.seconds = b->seconds;
    if (!pixels && r.image) continue;
    if (!rect || !r.image) {
      r.image = std::make_shared<Image>(with_strength(noisy, full, r.strength));
      if (r.id == a_) emit denoisedChanged();
      if (r.id == b_) emit compareChanged();
      continue;
    }
    if (r.image.use_count() > 1) r.image = std::make_shared<Image>(*r.image);  // copy on write, as above
    for (int64_t y = rect->y; y < rect->y + rect->height; ++y)
      for (int64_t x = rect->x; x < rect->x + rect->width; ++x)
        for (int c = 0; c < 3; ++c) r.image->at(x, y, c) = full.at(x, y, c);
    apply_strength(noisy, 0, *r.image, 0, *rect, rect->y, rect->height, r.strength);
    if (r.id == a_) emit denoisedTileChanged(*rect);
  }
}

}  // namespace residue::ui
