// Where Residue finds the data it ships (models, the OCIO fallback config, icons): the same lookup for the
// command-line tool, the viewer and the tests, from a build tree or from an installed package.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace residue {

// The folders that may hold shipped data, most specific first:
//   $RESIDUE_DATA_DIR (when set), <folder of the running executable>/../share/residue (an installed or
//   unpacked package, wherever it was put), the source tree's resources/ (a build tree), and
//   <CMAKE_INSTALL_PREFIX>/share/residue. Folders that do not exist are left out.
std::vector<std::filesystem::path> resource_dirs();

// The first `relative` path (e.g. "ocio/config.ocio") that exists under resource_dirs(), or nothing.
std::optional<std::filesystem::path> find_resource(const std::filesystem::path& relative);

// The running executable's path (from /proc/self/exe), or empty when it cannot be read.
std::filesystem::path executable_path();

}  // namespace residue
