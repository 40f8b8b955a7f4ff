// The renders opened lately (File > Open Recent), kept in the settings. A render is listed once however its path
// was typed (relative or absolute, a folder with or without "/"), under a name that tells alike files apart by
// their folder, with the reference it was last compared with.
#pragma once

#include <QString>
#include <QStringList>
#include <vector>

namespace residue::ui {

struct RecentRender {
  QStringList inputs;  // absolute, clean paths: a file, a folder, or single-AOV files
  QString reference;   // the reference file last loaded for it; empty when none was (or it was in the render)
  // "noisy_a.exr  ~/renders/kitchen", "kitchen/  ~/renders": the name, then the folder it is in.
  QString label() const;
};

class RecentRenders {
 public:
  static constexpr int kMax = 10;

  // The same render's inputs, written one way: absolute, without "." / ".." or a trailing "/".
  static QStringList normalised(const QStringList& inputs);

  std::vector<RecentRender> list() const;  // newest first
  // Puts the render first. `reference` empty keeps the one it was listed with.
  void add(const QStringList& inputs, const QString& reference = {});
  // The render's reference, when it is listed (a reference opened after the render).
  void setReference(const QStringList& inputs, const QString& reference);

 private:
  void store(const std::vector<RecentRender>& list);
};

}  // namespace residue::ui
