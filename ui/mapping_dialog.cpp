#include "ui/mapping_dialog.h"

#include <QComboBox>
#include <QCryptographicHash>
#include <QDialogButtonBox>
#include <QFormLayout>
#include <QLabel>
#include <QPushButton>
#include <QSettings>
#include <QVBoxLayout>

#include "core/aov/aov_loader.h"

namespace residue::ui {

std::vector<std::pair<QString, QStringList>> channel_groups(const QStringList& channels) {
  std::vector<std::pair<QString, QStringList>> groups;
  for (const QString& c : channels) {
    const qsizetype dot = c.lastIndexOf('.');
    const QString layer = dot < 0 ? QString() : c.left(dot);
    auto it = std::find_if(groups.begin(), groups.end(), [&](const auto& g) { return g.first == layer; });
    if (it == groups.end()) groups.push_back({layer, {c}});
    else it->second << c;
  }
  return groups;
}

QStringList mapping_flags(const std::map<AovRole, QStringList>& roles) {
  QStringList flags;
  for (const auto& [role, chans] : roles)
    if (!chans.isEmpty()) flags << QString("%1=%2").arg(QString::fromLatin1(to_string(role)), chans.join(','));
  return flags;
}

QString layout_key(const QStringList& channels) {
  QStringList sorted = channels;
  sorted.sort();
  return QString::fromLatin1(QCryptographicHash::hash(sorted.join('\n').toUtf8(), QCryptographicHash::Sha1).toHex());
}

std::optional<QStringList> remembered_mapping(const QStringList& channels) {
  QSettings s;
  const QVariant v = s.value("mappings/" + layout_key(channels));
  if (!v.isValid()) return std::nullopt;
  return v.toStringList();
}

void remember_mapping(const QStringList& channels, const QStringList& flags) {
  QSettings s;
  s.setValue("mappings/" + layout_key(channels), flags);
}

MappingDialog::MappingDialog(const std::filesystem::path& file, const QString& message, QWidget* parent)
    : QDialog(parent) {
  setWindowTitle(tr("Assign channels: %1").arg(QString::fromStdString(file.filename().string())));
  setObjectName("mappingDialog");
  try {
    for (const auto& c : list_channels(file).channels) channels_ << QString::fromStdString(c.name);
  } catch (const std::exception& e) {
    channels_.clear();
  }
  groups_ = channel_groups(channels_);

  auto* layout = new QVBoxLayout(this);
  auto* why = new QLabel(message, this);
  why->setWordWrap(true);
  why->setTextInteractionFlags(Qt::TextSelectableByMouse);
  layout->addWidget(why);
  auto* form = new QFormLayout;
  for (AovRole role : {AovRole::Color, AovRole::Albedo, AovRole::Normal, AovRole::Depth, AovRole::Variance,
                       AovRole::Reference}) {
    auto* combo = new QComboBox(this);
    combo->setObjectName(QString("map_%1").arg(QString::fromLatin1(to_string(role))));
    if (role != AovRole::Color) combo->addItem(tr("(none)"), QStringList());
    for (const auto& [layer, chans] : groups_) {
      const QString label = QString("%1  [%2]").arg(layer.isEmpty() ? tr("(root)") : layer, chans.join(", "));
      combo->addItem(label, chans);
      // Groups of more than the role needs can be picked channel by channel in the mapping text; the common
      // case (a layer of 3, or of 1 for depth) is one choice.
    }
    for (const QString& c : channels_) combo->addItem(tr("channel %1").arg(c), QStringList{c});
    combos_[role] = combo;
    form->addRow(QString::fromLatin1(to_string(role)) + (role == AovRole::Color ? tr(" (required)") : QString()), combo);
  }
  layout->addLayout(form);
  preview_ = new QLabel(this);
  preview_->setObjectName("mappingPreview");
  preview_->setWordWrap(true);
  layout->addWidget(preview_);
  auto* buttons = new QDialogButtonBox(QDialogButtonBox::Ok | QDialogButtonBox::Cancel, this);
  layout->addWidget(buttons);
  connect(buttons, &QDialogButtonBox::accepted, this, &QDialog::accept);
  connect(buttons, &QDialogButtonBox::rejected, this, &QDialog::reject);
  const auto update_preview = [this] { preview_->setText(tr("Mapping: %1").arg(flags().join("  "))); };
  for (auto& [role, combo] : combos_) connect(combo, &QComboBox::currentIndexChanged, this, update_preview);
  if (auto remembered = remembered_mapping(channels_)) {
    for (const QString& f : *remembered) {
      const auto role = aov_role_from_string(f.section('=', 0, 0).toStdString());
      if (role) choose(*role, f.section('=', 1).split(','));
    }
  }
  update_preview();
}

void MappingDialog::choose(AovRole role, const QStringList& channels) {
  auto it = combos_.find(role);
  if (it == combos_.end()) return;
  for (int i = 0; i < it->second->count(); ++i) {
    if (it->second->itemData(i).toStringList() == channels) {
      it->second->setCurrentIndex(i);
      return;
    }
  }
}

QStringList MappingDialog::flags() const {
  std::map<AovRole, QStringList> roles;
  for (const auto& [role, combo] : combos_) roles[role] = combo->currentData().toStringList();
  return mapping_flags(roles);
}

ChannelMapping MappingDialog::mapping() const {
  ChannelMapping m;
  for (const QString& f : flags()) m.add_flag(f.toStdString());
  return m;
}

}  // namespace residue::ui
