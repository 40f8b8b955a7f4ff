// LatestTask<R>: work on the thread pool of which only the newest request's result is shown.
//
// The viewer recomputes metrics, heatmaps and panes whenever the user changes something, often faster than a
// job finishes. start() supersedes whatever is running: an older job's result is dropped (the job can ask its
// Token whether it is still wanted and stop early), and busy() stays true until the newest result has been
// delivered on the GUI thread, so a caller that waits on busy() then reads the result sees the right one.
#pragma once

#include <QFutureWatcher>
#include <QObject>
#include <QtConcurrent/QtConcurrentRun>

#include <atomic>
#include <functional>
#include <memory>
#include <utility>
#include <vector>

namespace residue::ui {

template <class R>
class LatestTask {
 public:
  // Handed to the job: which request it is, and whether a newer one has started.
  class Token {
   public:
    Token(const std::atomic<int>* newest, int generation) : newest_(newest), generation_(generation) {}
    bool superseded() const { return newest_->load() != generation_; }
    int generation() const { return generation_; }

   private:
    const std::atomic<int>* newest_;
    int generation_;
  };

  // `deliver` runs on the GUI thread (the owner's) with the newest job's result.
  LatestTask(QObject* owner, std::function<void(R&&)> deliver)
      : deliver_(std::move(deliver)), watcher_(new QFutureWatcher<Slot>(owner)) {
    QObject::connect(watcher_, &QFutureWatcherBase::finished, owner, [this] {
      Slot s = watcher_->result();
      if (!s || s->generation != newest_.load()) return;  // superseded meanwhile
      delivered_ = true;
      deliver_(std::move(s->value));
    });
  }
  ~LatestTask() {  // jobs hold `this`: wait for every one still running, not only the newest
    for (auto& f : running_) f.waitForFinished();
  }
  LatestTask(const LatestTask&) = delete;
  LatestTask& operator=(const LatestTask&) = delete;

  // Runs work(const Token&) -> R on the pool; its result is delivered unless a newer start() or supersede()
  // came first.
  template <class Work>
  void start(Work work) {
    const int generation = ++newest_;
    delivered_ = false;
    std::erase_if(running_, [](const QFuture<Slot>& f) { return f.isFinished(); });
    QFuture<Slot> f = QtConcurrent::run([this, generation, work = std::move(work)]() -> Slot {
      const Token token(&newest_, generation);
      R value = work(token);
      if (token.superseded()) return nullptr;
      return std::make_shared<Held>(Held{generation, std::move(value)});
    });
    running_.push_back(f);
    watcher_->setFuture(f);
  }

  // Drops whatever is running, for a caller that answers the newest request at once, without a job.
  void supersede() {
    ++newest_;
    delivered_ = true;
  }

  bool busy() const { return !delivered_; }
  // True while `generation` is the newest request and its result has not been delivered (for partial results
  // a job posts itself, such as a preview).
  bool pending(int generation) const { return generation == newest_.load() && !delivered_; }

 private:
  struct Held {
    int generation;
    R value;
  };
  using Slot = std::shared_ptr<Held>;

  std::function<void(R&&)> deliver_;
  QFutureWatcher<Slot>* watcher_;  // owned by the owner QObject
  std::vector<QFuture<Slot>> running_;
  std::atomic<int> newest_{0};
  bool delivered_ = true;  // the newest request's result has been delivered (GUI thread only)
};

}  // namespace residue::ui
