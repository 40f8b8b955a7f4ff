#include "ui/render_list.h"

#include <QFileInfo>
#include <QHBoxLayout>
#include <QLabel>
#include <QListWidget>
#include <QPushButton>
#include <QSignalBlocker>
#include <QVBoxLayout>

#include "ui/session.h"

namespace residue::ui {

RenderList::RenderList(Session* session, QWidget* parent) : QWidget(parent), session_(session) {
  setObjectName("renderList");
  auto* layout = new QVBoxLayout(this);
  auto* caption = new QLabel(tr("Renders open (PgUp / PgDown step through them); each keeps its results, A and B, "
                                "region and view"), this);
  caption->setWordWrap(true);
  layout->addWidget(caption);
  list_ = new QListWidget(this);
  list_->setObjectName("renderListItems");
  layout->addWidget(list_, 1);
  auto* buttons = new QHBoxLayout;
  close_ = new QPushButton(tr("Close"), this);
  close_->setObjectName("closeRenderButton");
  close_->setToolTip(tr("Close the render shown, with its results (Ctrl+W)"));
  buttons->addStretch(1);
  buttons->addWidget(close_);
  layout->addLayout(buttons);

  connect(list_, &QListWidget::currentRowChanged, this, [this](int row) {
    if (row >= 0 && row != session_->currentRender()) session_->showRender(row);
  });
  connect(close_, &QPushButton::clicked, this, [this] { session_->closeRender(session_->currentRender()); });
  connect(session_, &Session::renderListChanged, this, &RenderList::rebuild);
  connect(session_, &Session::resultsChanged, this, &RenderList::rebuild);
  rebuild();
}

void RenderList::rebuild() {
  const QSignalBlocker block(list_);
  list_->clear();
  QStringList titles;
  for (int i = 0; i < session_->renderCount(); ++i) titles << session_->renderTitle(i);
  for (int i = 0; i < session_->renderCount(); ++i) {
    const int n = session_->renderResultCount(i);
    const QString results = n == 0 ? QString() : n == 1 ? tr("    1 result") : tr("    %1 results").arg(n);
    // Alike names (every scene's noisy_a.exr) say their folder.
    QString title = titles[i];
    const QStringList inputs = session_->renderInputs(i);
    if (titles.count(title) > 1 && !inputs.isEmpty())
      title += "  (" + QFileInfo(QFileInfo(inputs.front()).absolutePath()).fileName() + ")";
    auto* item = new QListWidgetItem(title + results, list_);
    item->setToolTip(session_->renderInputs(i).join('\n'));  // alike names from different folders
    if (i == session_->currentRender()) {
      QFont f = item->font();
      f.setBold(true);
      item->setFont(f);
    }
  }
  list_->setCurrentRow(session_->currentRender());
  close_->setEnabled(session_->currentRender() >= 0);
}

}  // namespace residue::ui
