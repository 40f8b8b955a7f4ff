// HelpOverlay: the keyboard shortcuts, drawn over the canvas (? toggles it, Esc or a click hides it).
#pragma once

#include <QFont>
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

  // How the rows are laid out at the overlay's size: the font, columns of rows, and whether descriptions had to
  // be shortened (only when not even a 7 pt font fits them).
  struct Plan {
    QFont font;
    int line = 0, key_width = 0, what_width = 0, columns = 1, rows = 0, column_width = 0;
    bool shortened = false;
  };
  Plan plan() const;

 protected:
  void paintEvent(QPaintEvent*) override;
  bool eventFilter(QObject* watched, QEvent* event) override;  // follows the canvas's size
  void mousePressEvent(QMouseEvent*) override;

 private:
  static constexpr int kMargin = 40;  // kept clear around the plate
  std::vector<std::pair<QString, QString>> shortcuts_;
};

}  // namespace residue::ui
