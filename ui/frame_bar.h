// FrameBar: the controls of a sequence's frames under the image: first / previous / play / next / last, a
// slider and the frame number. It only says what the user asked for; MainWindow steps the session
// (ui/main_window_frames.cpp), whose tool bar holds it, shown when the render is a frame of a sequence.
#pragma once

#include <QWidget>
#include <cstdint>
#include <vector>

class QLabel;
class QSlider;
class QSpinBox;
class QToolButton;

namespace residue::ui {

class FrameBar : public QWidget {
  Q_OBJECT
 public:
  explicit FrameBar(QWidget* parent = nullptr);

  // The frames of the sequence (ascending) and the one shown.
  void setFrames(const std::vector<int64_t>& frames, int64_t current);
  void setCurrent(int64_t frame);
  int64_t current() const;
  void setPlaying(bool playing);  // the play button's state (MainWindow plays)
  bool playing() const { return playing_; }
  int fps() const;                // frames a second asked for while playing
  void setStatus(const QString& text);  // after the frame number: "frame 3 of 16, 2 results", "playing 11.8 fps"

 signals:
  void frameRequested(qint64 frame);
  void playToggled(bool play);

 private:
  std::vector<int64_t> frames_;
  QToolButton* play_ = nullptr;
  QSlider* slider_ = nullptr;
  QSpinBox* number_ = nullptr;
  QSpinBox* fps_ = nullptr;
  QLabel* status_ = nullptr;
  bool playing_ = false;
  bool updating_ = false;
};

}  // namespace residue::ui
