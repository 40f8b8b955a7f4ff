// RenderList: the side bar's list of the renders held open (the image list, as tev's), each with its number of
// results. Clicking one shows it as it was left; Close (Ctrl+W) closes the one shown. It lists and asks: the
// Session holds the renders.
#pragma once

#include <QWidget>

class QListWidget;
class QPushButton;

namespace residue::ui {

class Session;

class RenderList : public QWidget {
  Q_OBJECT
 public:
  explicit RenderList(Session* session, QWidget* parent = nullptr);
  QListWidget* list() const { return list_; }

 private:
  void rebuild();

  Session* session_;
  QListWidget* list_ = nullptr;
  QPushButton* close_ = nullptr;
};

}  // namespace residue::ui
