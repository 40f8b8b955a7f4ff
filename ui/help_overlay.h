// HelpOverlay: the keyboard shortcuts, drawn over the canvas (? toggles it, Esc or a click hides it).
#pragma once

#include <QWidget>
#include <utility>
#include <vector>

namespace residue::ui {

class HelpOverlay : public QWidget {
  Q_OBJECT
 public:
  explicit HelpOverlay(QWidget* parent);
  void setShortcuts(std::vector<std::pair<QString, QString>> shortcuts);  // (keys, what they do), in display order
  void toggle();

 protected:
  void paintEvent(QPaintEvent*) override;
  bool eventFilter(QObject* watched, QEvent* event) override;  // follows the canvas's size
  void mousePressEvent(QMouseEvent*) override;

 private:
  std::vector<std::pair<QString, QString>> shortcuts_;
};

}  // namespace residue::ui
