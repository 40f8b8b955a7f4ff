#include "ui/recent_renders.h"

#include <QDir>
#include <QFileInfo>
#include <QSettings>
#include <QVariantMap>
#include <algorithm>

namespace residue::ui {

namespace {
constexpr const char* kKey = "recentRenders";
constexpr const char* kOldKey = "recentFiles";  // inputs joined by '\n', no reference

// A folder under the home folder as "~/...", so that the part that tells renders apart is what is left to read.
QString shortFolder(const QString& folder) {
  const QString home = QDir::homePath();
  if (folder == home) return QStringLiteral("~");
  if (folder.startsWith(home + '/')) return "~" + folder.mid(home.size());
  return QDir::toNativeSeparators(folder);
}
}  // namespace

QString RecentRender::label() const {
  QStringList names;
  QString folder;
  for (const QString& f : inputs) {
    const QFileInfo info(f);
    names << (info.isDir() ? info.fileName() + '/' : info.fileName());
    if (folder.isEmpty()) folder = info.absolutePath();
  }
  return names.join(", ") + "    " + shortFolder(folder);
}

QStringList RecentRenders::normalised(const QStringList& inputs) {
  QStringList out;
  for (const QString& f : inputs) out << QDir::cleanPath(QFileInfo(f).absoluteFilePath());
  return out;
}

std::vector<RecentRender> RecentRenders::list() const {
  QSettings s;
  std::vector<RecentRender> out;
  if (s.contains(kKey)) {
    for (const QVariant& v : s.value(kKey).toList()) {
      const QVariantMap m = v.toMap();
      RecentRender r{m.value("inputs").toStringList(), m.value("reference").toString()};
      if (!r.inputs.isEmpty()) out.push_back(std::move(r));
    }
  } else {
    for (const QString& entry : s.value(kOldKey).toStringList()) out.push_back({normalised(entry.split('\n')), {}});
  }
  return out;
}

void RecentRenders::add(const QStringList& inputs, const QString& reference) {
  RecentRender entry{normalised(inputs), reference.isEmpty() ? QString() : normalised({reference}).front()};
  std::vector<RecentRender> all = list();
  const auto same = std::find_if(all.begin(), all.end(), [&](const RecentRender& r) { return r.inputs == entry.inputs; });
  if (same != all.end()) {
    if (entry.reference.isEmpty()) entry.reference = same->reference;
    all.erase(same);
  }
  all.insert(all.begin(), std::move(entry));
  if (all.size() > kMax) all.resize(kMax);
  store(all);
}

void RecentRenders::setReference(const QStringList& inputs, const QString& reference) {
  std::vector<RecentRender> all = list();
  const QStringList key = normalised(inputs);
  for (RecentRender& r : all)
    if (r.inputs == key) r.reference = reference.isEmpty() ? QString() : normalised({reference}).front();
  store(all);
}

void RecentRenders::store(const std::vector<RecentRender>& list) {
  QVariantList out;
  for (const RecentRender& r : list) out << QVariantMap{{"inputs", r.inputs}, {"reference", r.reference}};
  QSettings s;
  s.setValue(kKey, out);
  s.remove(kOldKey);
}

}  // namespace residue::ui
