#include "core/util/resources.h"

#include <cstdlib>
#include <system_error>

namespace residue {

std::filesystem::path executable_path() {
  std::error_code ec;
  auto p = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::filesystem::path{} : p;
}

std::vector<std::filesystem::path> resource_dirs() {
  std::vector<std::filesystem::path> candidates;
  if (const char* env = std::getenv("RESIDUE_DATA_DIR"); env && *env) candidates.emplace_back(env);
  if (const auto exe = executable_path(); !exe.empty())
    candidates.push_back(exe.parent_path().parent_path() / "share" / "residue");
  candidates.emplace_back(RESIDUE_SOURCE_RESOURCES);
  candidates.emplace_back(RESIDUE_INSTALL_DATADIR);

  std::vector<std::filesystem::path> dirs;
  for (auto& c : candidates) {
    std::error_code ec;
    if (!std::filesystem::is_directory(c, ec)) continue;
    auto canonical = std::filesystem::weakly_canonical(c, ec);
    if (ec) canonical = c;
    bool seen = false;
    for (const auto& d : dirs) seen = seen || d == canonical;
    if (!seen) dirs.push_back(canonical);
  }
  return dirs;
}

std::optional<std::filesystem::path> find_resource(const std::filesystem::path& relative) {
  for (const auto& d : resource_dirs()) {
    std::error_code ec;
    if (std::filesystem::exists(d / relative, ec)) return d / relative;
  }
  return std::nullopt;
}

}  // namespace residue
