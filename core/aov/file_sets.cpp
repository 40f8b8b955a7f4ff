#include "core/aov/file_sets.h"

#include <algorithm>
#include <cctype>

#include "core/aov/conventions.h"
#include "core/util/error.h"

namespace residue {
namespace fs = std::filesystem;
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// The role a file name suggests, or nullopt for "no keyword" (a colour candidate).
std::optional<AovRole> role_from_name(const fs::path& file) {
  const std::string name = lower(file.filename().string());
  const std::string stem = lower(file.stem().string());
  auto has = [&](const char* k) { return name.find(k) != std::string::npos; };
  if (has("variance") || has(".var.")) return AovRole::Variance;
  if (has("albedo") || has(".alb.")) return AovRole::Albedo;
  if (has("normal") || has(".nrm.")) return AovRole::Normal;
  if (has("depth") || has(".z.") || stem == "z") return AovRole::Depth;
  if (has("reference") || has("_ref.") || stem == "ref") return AovRole::Reference;
  return std::nullopt;
}

}  // namespace

fs::path colour_file_in_folder(const fs::path& folder) {
  std::vector<fs::path> candidates;
  std::string expected;
  for (const auto& convention : file_set_conventions()) {
    for (auto& file : convention->colour_files_in(folder)) candidates.push_back(std::move(file));
    expected += (expected.empty() ? "" : " or ") + convention->colour_file_pattern();
  }
  if (candidates.size() == 1) return candidates.front();
  if (candidates.empty())
    throw Error(ErrorKind::Input, "folder '" + folder.string() + "': no colour file found; expected " + expected +
                                      ", or give the file itself");
  std::string list;
  for (const auto& c : candidates) list += " " + c.filename().string();
  throw Error(ErrorKind::Input, "folder '" + folder.string() + "' holds several colour files:" + list +
                                    "; give the one to use");
}

FileSet sibling_file_set(const fs::path& colour_file) {
  FileSet set;
  set.files[AovRole::Color] = colour_file;
  for (const auto& convention : file_set_conventions()) {
    if (!convention->claims(colour_file)) continue;
    set.convention = convention->name();
    set.normal_space = convention->normal_space();
    set.depth_kind = convention->depth_kind();
    for (const auto& [role, path] : convention->siblings(colour_file))
      if (fs::is_regular_file(path)) set.files.emplace(role, path);
    break;
  }
  return set;
}

FileSet file_set_from_names(const std::vector<fs::path>& files) {
  FileSet set;
  set.convention = "files named by AOV";
  for (const auto& f : files) {
    const AovRole role = role_from_name(f).value_or(AovRole::Color);
    if (set.files.count(role))
      throw Error(ErrorKind::Input, "both '" + set.files[role].string() + "' and '" + f.string() +
                                        "' look like the " + to_string(role) +
                                        " AOV; give one, or map them explicitly with --map");
    set.files[role] = f;
  }
  if (!set.files.count(AovRole::Color))
    throw Error(ErrorKind::Input, "none of the given files is a colour image (every name says albedo, normal, "
                                  "depth, variance or reference); use --map color=FILE");
  return set;
}

}  // namespace residue
