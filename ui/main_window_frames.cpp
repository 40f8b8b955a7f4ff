// MainWindow's sequences: the frame bar, stepping and playing through the frames of a sequence (the session keeps
// each frame's results), the temporal error map, and denoising every frame in turn.
#include <QAction>
#include <QStatusBar>
#include <QTimer>
#include <QToolBar>
#include <algorithm>

#include "core/temporal/warped_error.h"
#include "ui/denoise_panel.h"
#include "ui/frame_bar.h"
#include "ui/main_window.h"
#include "ui/metrics_panel.h"

namespace residue::ui {

void MainWindow::buildFrameBar() {
  frame_bar_ = new FrameBar(this);
  frames_toolbar_ = new QToolBar(tr("Frames"), this);
  frames_toolbar_->setObjectName("framesToolBar");
  frames_toolbar_->setMovable(false);
  frames_toolbar_->addWidget(frame_bar_);
  addToolBar(Qt::BottomToolBarArea, frames_toolbar_);
  frames_toolbar_->hide();
  play_timer_ = new QTimer(this);
  play_timer_->setSingleShot(true);
  connect(play_timer_, &QTimer::timeout, this, [this] { stepFrame(+1); });
  connect(frame_bar_, &FrameBar::frameRequested, this, [this](qint64 f) { goToFrame(f); });
  connect(frame_bar_, &FrameBar::playToggled, this, &MainWindow::setPlaying);
  connect(session_, &Session::loaded, this, &MainWindow::updateFrameBar);
  connect(this, &MainWindow::panesRendered, this, &MainWindow::playNext);
  // Denoising every frame: the next frame once this one's result is in.
  connect(session_, &Session::frameChanged, this, [this] {
    if (every_frame_) denoise_->start();
  });
  connect(denoise_, &DenoisePanel::finished, this, [this](bool ok, const QString& message) {
    if (!every_frame_) return;
    const auto& seq = session_->sequence();
    const int i = seq ? seq->indexOf(session_->frame()) : -1;
    if (!ok || i < 0 || i + 1 >= static_cast<int>(seq->frames.size())) {
      every_frame_ = false;
      say(ok ? tr("Every frame denoised: %1").arg(session_->denoisedDescription())
                                  : tr("Denoising every frame stopped at frame %1: %2").arg(session_->frame()).arg(message),
                               15000);
      updateFrameBar();
      return;
    }
    goToFrame(seq->frames[static_cast<size_t>(i + 1)]);
  });
}

void MainWindow::updateFrameBar() {
  const auto& seq = session_->sequence();
  if (!seq) {
    playing_ = false;
    play_timer_->stop();
    frame_bar_->setPlaying(false);
    frames_toolbar_->hide();
    frame_bar_->setFrames({}, 0);
    return;
  }
  frame_bar_->setFrames(seq->frames, session_->frame());
  frames_toolbar_->show();
  const int i = seq->indexOf(session_->frame());
  QString status = tr("%1 of %2").arg(i + 1).arg(seq->frames.size());
  if (every_frame_) status += tr(", denoising every frame");
  if (playing_ && shown_at_.size() >= 2) {
    const double seconds = static_cast<double>(shown_at_.back() - shown_at_.front()) / 1000.0;
    if (seconds > 0) status += tr(", playing at %1 fps").arg(static_cast<double>(shown_at_.size() - 1) / seconds, 0, 'f', 1);
  }
  frame_bar_->setStatus(status);
}

bool MainWindow::goToFrame(int64_t frame) {
  const auto& seq = session_->sequence();
  if (!seq || !seq->contains(frame)) return false;
  if (frame == session_->frame() && !session_->loading()) return true;
  frame_clock_.restart();
  frame_bar_->setCurrent(frame);
  return session_->showFrame(frame);
}

void MainWindow::stepFrame(int step) {
  const auto& seq = session_->sequence();
  if (!seq) return;
  const int n = static_cast<int>(seq->frames.size());
  int i = seq->indexOf(session_->frame()) + step;
  if (playing_) i = (i % n + n) % n;  // a shot plays in a loop
  if (i < 0 || i >= n) return;
  goToFrame(seq->frames[static_cast<size_t>(i)]);
}

void MainWindow::setPlaying(bool play) {
  if (play && !session_->sequence()) play = false;
  playing_ = play;
  frame_bar_->setPlaying(play);
  shown_at_.clear();
  play_clock_.restart();
  if (!play) play_timer_->stop();
  else playNext();
  updateFrameBar();
}

void MainWindow::playNext() {
  // Called as the panes arrive (panesRendered), while their task still counts as running: not rendering().
  if (!playing_ || !session_->hasStack() || session_->loading() || play_timer_->isActive()) return;
  shown_at_.push_back(play_clock_.elapsed());
  if (shown_at_.size() > 25) shown_at_.erase(shown_at_.begin());
  updateFrameBar();
  // The frame is on screen: the next one is asked for once this one has had its time (or at once if loading it
  // took longer: a frame is never skipped, so a slow disk plays slower rather than jumping).
  const qint64 interval = 1000 / std::max(1, frame_bar_->fps());
  const qint64 spent = frame_clock_.isValid() ? frame_clock_.elapsed() : interval;  // none asked for yet
  play_timer_->start(static_cast<int>(std::clamp<qint64>(interval - spent, 0, interval)));
}

void MainWindow::denoiseEveryFrame() {
  const auto& seq = session_->sequence();
  if (!seq) {
    last_error_ = tr("Open a frame of a sequence first (a file named like shot.0001.exr, with its other frames beside it).");
    say(last_error_, 8000);
    return;
  }
  if (denoise_->running()) return;
  setPlaying(false);
  every_frame_ = true;
  updateFrameBar();
  if (session_->frame() == seq->frames.front()) denoise_->start();
  else goToFrame(seq->frames.front());
}

void MainWindow::computeTemporalMap() {
  const auto stack = session_->stack();
  const auto prev = session_->frameStack(session_->frame() - 1);
  QString subject;
  std::shared_ptr<const Image> image, previous;
  const auto of_result = [&](int id) {
    const Result* r = session_->result(id);
    if (!r || !r->done()) return;
    subject = session_->resultName(id);
    image = r->image;
    previous = session_->previousImage(r);
  };
  switch (heatmap_->of()) {
    case HeatmapPanel::Of::A: of_result(session_->a()); break;
    case HeatmapPanel::Of::B: of_result(session_->b()); break;
    case HeatmapPanel::Of::Noisy:
      subject = tr("the noisy input");
      image = std::shared_ptr<const Image>(stack, &stack->color.image);
      previous = session_->previousImage(nullptr);
      break;
    case HeatmapPanel::Of::AgainstB: break;
  }
  QString missing;
  if (heatmap_->of() == HeatmapPanel::Of::AgainstB) missing = tr("the temporal map is of one image: A, B or the noisy input");
  else if (!session_->sequence()) missing = tr("the temporal map needs a frame of a sequence");
  else if (!stack->motion) missing = tr("the temporal map needs the frames' motion vectors");
  else if (!prev || !stack->reference || !prev->reference) missing = tr("the temporal map needs frame t-1 and both frames' references");
  else if (!image) missing = tr("no result to map yet");
  else if (!previous) missing = tr("%1 has no result on frame t-1 (denoise it there too)").arg(subject);
  if (!missing.isEmpty()) return heatmap_->computeMap(nullptr, subject, missing);
  const double eps = metrics_->options().eps;
  heatmap_->computeMap([stack, prev, image, previous, eps] { return compensated_temporal_map(*stack, *image, *prev, *previous, eps); },
                       subject, QString());
}

}  // namespace residue::ui
