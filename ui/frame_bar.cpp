#include "ui/frame_bar.h"

#include <QHBoxLayout>
#include <QLabel>
#include <QSlider>
#include <QSpinBox>
#include <QStyle>
#include <QToolButton>
#include <algorithm>

namespace residue::ui {

FrameBar::FrameBar(QWidget* parent) : QWidget(parent) {
  setObjectName("frameBar");
  auto* row = new QHBoxLayout(this);
  row->setContentsMargins(6, 2, 6, 2);
  const auto button = [this, row](QStyle::StandardPixmap icon, const QString& name, const QString& tip) {
    auto* b = new QToolButton(this);
    b->setObjectName(name);
    b->setIcon(style()->standardIcon(icon));
    b->setToolTip(tip);
    b->setAutoRaise(true);
    row->addWidget(b);
    return b;
  };
  auto* first = button(QStyle::SP_MediaSkipBackward, "firstFrame", tr("First frame (Home)"));
  auto* prev = button(QStyle::SP_MediaSeekBackward, "previousFrame", tr("Previous frame (Left)"));
  play_ = button(QStyle::SP_MediaPlay, "playFrames", tr("Play / pause (P): each frame is shown once it is loaded"));
  auto* next = button(QStyle::SP_MediaSeekForward, "nextFrame", tr("Next frame (Right)"));
  auto* last = button(QStyle::SP_MediaSkipForward, "lastFrame", tr("Last frame (End)"));
  slider_ = new QSlider(Qt::Horizontal, this);
  slider_->setObjectName("frameSlider");
  slider_->setToolTip(tr("The frames of the sequence"));
  row->addWidget(slider_, 1);
  auto* label = new QLabel(tr("frame"), this);
  row->addWidget(label);
  number_ = new QSpinBox(this);
  number_->setObjectName("frameNumber");
  number_->setKeyboardTracking(false);
  number_->setToolTip(tr("The frame shown; type one to go there"));
  row->addWidget(number_);
  fps_ = new QSpinBox(this);
  fps_->setObjectName("framesPerSecond");
  fps_->setRange(1, 60);
  fps_->setValue(12);
  fps_->setSuffix(tr(" fps"));
  fps_->setToolTip(tr("Frames a second while playing, at most (a frame still loading is waited for)"));
  row->addWidget(fps_);
  status_ = new QLabel(this);
  status_->setObjectName("frameStatus");
  row->addWidget(status_);

  const auto go_index = [this](int i) {
    if (frames_.empty()) return;
    emit frameRequested(frames_[static_cast<size_t>(std::clamp(i, 0, static_cast<int>(frames_.size()) - 1))]);
  };
  connect(first, &QToolButton::clicked, this, [go_index] { go_index(0); });
  connect(last, &QToolButton::clicked, this, [this, go_index] { go_index(static_cast<int>(frames_.size()) - 1); });
  connect(prev, &QToolButton::clicked, this, [this, go_index] { go_index(slider_->value() - 1); });
  connect(next, &QToolButton::clicked, this, [this, go_index] { go_index(slider_->value() + 1); });
  connect(play_, &QToolButton::clicked, this, [this] { emit playToggled(!playing_); });
  connect(slider_, &QSlider::valueChanged, this, [this, go_index](int i) {
    if (!updating_) go_index(i);
  });
  connect(number_, &QSpinBox::valueChanged, this, [this](int f) {
    if (updating_ || frames_.empty()) return;
    // A number between frames goes to the nearest frame at or after it.
    const auto it = std::lower_bound(frames_.begin(), frames_.end(), static_cast<int64_t>(f));
    emit frameRequested(it == frames_.end() ? frames_.back() : *it);
  });
}

void FrameBar::setFrames(const std::vector<int64_t>& frames, int64_t current) {
  frames_ = frames;
  if (frames_.empty()) return;
  updating_ = true;
  slider_->setRange(0, static_cast<int>(frames_.size()) - 1);
  number_->setRange(static_cast<int>(frames_.front()), static_cast<int>(frames_.back()));
  updating_ = false;
  setCurrent(current);
}

void FrameBar::setCurrent(int64_t frame) {
  const auto it = std::lower_bound(frames_.begin(), frames_.end(), frame);
  if (it == frames_.end() || *it != frame) return;
  updating_ = true;
  slider_->setValue(static_cast<int>(it - frames_.begin()));
  number_->setValue(static_cast<int>(frame));
  updating_ = false;
}

int64_t FrameBar::current() const {
  return frames_.empty() ? 0 : frames_[static_cast<size_t>(std::clamp(slider_->value(), 0, static_cast<int>(frames_.size()) - 1))];
}

void FrameBar::setPlaying(bool playing) {
  playing_ = playing;
  play_->setIcon(style()->standardIcon(playing ? QStyle::SP_MediaPause : QStyle::SP_MediaPlay));
}

int FrameBar::fps() const { return fps_->value(); }

void FrameBar::setStatus(const QString& text) { status_->setText(text); }

}  // namespace residue::ui
