// What the viewer remembers across restarts: the window's geometry and docks, the layout, the OpenColorIO display
// and view, the theme, the model and precision, and how the heatmap is drawn. One list of controls, saved by
// their object names when the window closes and set again by restoreSettings() (residue calls it at start; the
// tests and --screenshot start from the defaults).
#include <QApplication>
#include <QCheckBox>
#include <QComboBox>
#include <QDockWidget>
#include <QLineEdit>
#include <QPalette>
#include <QSettings>
#include <QStyle>
#include <QStyleFactory>

#include "ui/denoise_panel.h"
#include "ui/main_window.h"

namespace residue::ui {

namespace {
constexpr const char* kGroup = "viewer";

// The remembered controls, by object name: combos by their text (an index would point at another entry once a
// list changes), check boxes by their state, typed fields by their text.
QVariant valueOf(const QWidget* w) {
  if (const auto* c = qobject_cast<const QComboBox*>(w)) return c->currentText();
  if (const auto* b = qobject_cast<const QCheckBox*>(w)) return b->isChecked();
  if (const auto* e = qobject_cast<const QLineEdit*>(w)) return e->text();
  return {};
}

void setValueOf(QWidget* w, const QVariant& v) {
  if (!v.isValid()) return;
  if (auto* c = qobject_cast<QComboBox*>(w)) {
    if (const int i = c->findText(v.toString()); i >= 0) c->setCurrentIndex(i);
  } else if (auto* b = qobject_cast<QCheckBox*>(w)) {
    b->setChecked(v.toBool());
  } else if (auto* e = qobject_cast<QLineEdit*>(w)) {
    e->setText(v.toString());
    emit e->editingFinished();
  }
}
}  // namespace

std::vector<QWidget*> MainWindow::rememberedControls() const {
  std::vector<QWidget*> out;
  // Display before view: the views listed depend on the display.
  for (const char* name : {"layoutBox", "displayBox", "viewBox", "precision", "heatmapKind", "heatmapOf",
                           "heatmapDisplay", "heatmapColormap", "heatmapRangeMode", "heatmapLog", "heatmapLo",
                           "heatmapHi"})
    if (auto* w = findChild<QWidget*>(name)) out.push_back(w);
  return out;
}

void MainWindow::restoreSettings() {
  remember_settings_ = true;
  QSettings s;
  s.beginGroup(kGroup);
  setTheme(themeFromName(s.value("theme").toString()).value_or(Theme::System));
  if (s.contains("geometry")) restoreGeometry(s.value("geometry").toByteArray());
  if (s.contains("state")) restoreState(s.value("state").toByteArray());
  for (QWidget* w : rememberedControls()) setValueOf(w, s.value(w->objectName()));
  if (const QString model = s.value("model").toString(); !model.isEmpty()) denoise_->selectModel(model);
  s.endGroup();
}

void MainWindow::saveSettings() const {
  if (!remember_settings_) return;
  QSettings s;
  s.beginGroup(kGroup);
  s.setValue("theme", themeName(theme_));
  s.setValue("geometry", saveGeometry());
  s.setValue("state", saveState());
  for (const QWidget* w : rememberedControls()) s.setValue(w->objectName(), valueOf(w));
  s.setValue("model", denoise_->selectedModel());
  s.endGroup();
}

// ---------------------------------------------------------------------------------------------------------------
// Theme

QString MainWindow::themeName(Theme t) {
  return t == Theme::Dark ? QStringLiteral("dark") : t == Theme::Light ? QStringLiteral("light") : QStringLiteral("system");
}

std::optional<MainWindow::Theme> MainWindow::themeFromName(const QString& name) {
  for (Theme t : {Theme::System, Theme::Light, Theme::Dark})
    if (name.compare(themeName(t), Qt::CaseInsensitive) == 0) return t;
  return std::nullopt;
}

void MainWindow::setTheme(Theme theme) {
  theme_ = theme;
  static const QString platform_style = QApplication::style()->name();  // what "as the system" goes back to
  if (theme == Theme::System) {
    QApplication::setStyle(QStyleFactory::create(platform_style));
    QApplication::setPalette(QApplication::style()->standardPalette());
  } else {
    // Fusion draws every control from the palette, so a dark palette darkens all of them (the platform's style may
    // not). Neutral greys: nothing around the image tints how its colours are judged.
    QApplication::setStyle(QStyleFactory::create("Fusion"));
    QPalette p = QApplication::style()->standardPalette();
    if (theme == Theme::Dark) {
      const QColor window(45, 45, 45), base(30, 30, 30), text(220, 220, 220), disabled(120, 120, 120);
      p.setColor(QPalette::Window, window);
      p.setColor(QPalette::WindowText, text);
      p.setColor(QPalette::Base, base);
      p.setColor(QPalette::AlternateBase, window);
      p.setColor(QPalette::ToolTipBase, base);
      p.setColor(QPalette::ToolTipText, text);
      p.setColor(QPalette::PlaceholderText, disabled);
      p.setColor(QPalette::Text, text);
      p.setColor(QPalette::Button, window);
      p.setColor(QPalette::ButtonText, text);
      p.setColor(QPalette::BrightText, Qt::white);
      p.setColor(QPalette::Highlight, QColor(70, 110, 160));
      p.setColor(QPalette::HighlightedText, Qt::white);
      p.setColor(QPalette::Link, QColor(120, 170, 230));
      p.setColor(QPalette::Mid, QColor(60, 60, 60));
      p.setColor(QPalette::Dark, QColor(25, 25, 25));
      for (auto role : {QPalette::WindowText, QPalette::Text, QPalette::ButtonText})
        p.setColor(QPalette::Disabled, role, disabled);
    }
    QApplication::setPalette(p);
  }
  for (QAction* a : theme_actions_) a->setChecked(a->data().toInt() == static_cast<int>(theme));
}

}  // namespace residue::ui
