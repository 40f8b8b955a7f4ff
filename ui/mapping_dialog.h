// MappingDialog: when a file's channels cannot be mapped to AOVs automatically, the user assigns them: one
// choice per role (colour required), among the file's layers (channel groups such as "diffuse.R,G,B").
// The mapping is remembered per channel layout (QSettings), so the next file of the same layout just opens.
#pragma once

#include <QDialog>
#include <QStringList>
#include <filesystem>
#include <map>
#include <optional>

#include "core/aov/channel_mapping.h"

class QComboBox;
class QLabel;

namespace residue::ui {

// A file's channels grouped into layers: "diffuse" -> {diffuse.R, diffuse.G, diffuse.B}; root channels
// (R, G, B, Z) form the layer "" (shown as "(root)"). Order as stored.
std::vector<std::pair<QString, QStringList>> channel_groups(const QStringList& channels);

// "role=ch,ch,ch" flags for ChannelMapping::add_flag, from role -> channels.
QStringList mapping_flags(const std::map<AovRole, QStringList>& roles);

// A key that identifies a channel layout (sorted names), for remembering mappings.
QString layout_key(const QStringList& channels);
std::optional<QStringList> remembered_mapping(const QStringList& channels);
void remember_mapping(const QStringList& channels, const QStringList& flags);

class MappingDialog : public QDialog {
  Q_OBJECT
 public:
  // `message`: why the automatic mapping failed (core's error text).
  MappingDialog(const std::filesystem::path& file, const QString& message, QWidget* parent = nullptr);
  QStringList flags() const;        // the chosen mapping, for ChannelMapping::add_flag
  ChannelMapping mapping() const;
  QStringList channels() const { return channels_; }
  // Preselects `channels` (names) for `role`, for tests and the remembered mapping.
  void choose(AovRole role, const QStringList& channels);

 private:
  QStringList channels_;
  std::vector<std::pair<QString, QStringList>> groups_;
  std::map<AovRole, QComboBox*> combos_;
  QLabel* preview_ = nullptr;
};

}  // namespace residue::ui
