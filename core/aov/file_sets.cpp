#include "core/aov/file_sets.h"

#include <algorithm>
#include <cctype>
#include <regex>

#include "core/util/error.h"

namespace residue {
namespace fs = std::filesystem;
namespace {

const std::regex kOidnColour(R"(^(.*)_(\d+spp)\.hdr\.exr$)", std::regex::icase);

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
  if (fs::exists(folder / "color.exr")) return folder / "color.exr";
  std::vector<fs::path> candidates;
  for (const auto& entry : fs::directory_iterator(folder))
    if (std::regex_match(entry.path().filename().string(), kOidnColour)) candidates.push_back(entry.path());
  std::sort(candidates.begin(), candidates.end());
  if (candidates.size() == 1) return candidates.front();
  if (candidates.empty())
    throw Error(ErrorKind::Input, "folder '" + folder.string() +
                                      "': no colour file found; expected color.exr (Tungsten) or "
                                      "NAME_NNNNspp.hdr.exr (OIDN data set), or give the file itself");
  std::string list;
  for (const auto& c : candidates) list += " " + c.filename().string();
  throw Error(ErrorKind::Input, "folder '" + folder.string() + "' holds several colour files:" + list +
                                    "; give the one to use");
}

FileSet sibling_file_set(const fs::path& colour_file) {
  FileSet set;
  set.files[AovRole::Color] = colour_file;
  const fs::path dir = colour_file.parent_path();
  const std::string name = colour_file.filename().string();
  auto add_if = [&](AovRole role, const fs::path& p) {
    if (!set.files.count(role) && fs::is_regular_file(p)) set.files[role] = p;
  };
  std::smatch m;
  if (std::regex_match(name, m, kOidnColour)) {
    set.convention = "OIDN data set";
    const std::string base = m[1].str() + "_" + m[2].str();
    add_if(AovRole::Albedo, dir / (base + ".alb.exr"));
    add_if(AovRole::Normal, dir / (base + ".nrm.exr"));
    add_if(AovRole::Depth, dir / (base + ".z.exr"));
    add_if(AovRole::Reference, dir / (m[1].str() + "_ref.hdr.exr"));
    return set;
  }
  set.convention = "Tungsten file set";
  const std::string stem = colour_file.stem().string();
  add_if(AovRole::Albedo, dir / "albedo.exr");
  add_if(AovRole::Normal, dir / "normal.exr");
  add_if(AovRole::Depth, dir / "depth.exr");
  add_if(AovRole::Variance, dir / (stem + "Variance.exr"));
  if (stem != "reference") add_if(AovRole::Reference, dir / "reference.exr");
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
