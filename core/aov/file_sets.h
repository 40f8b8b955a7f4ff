// Single-AOV file sets: renders that write one file per buffer. The renderers' own layouts (Tungsten, OIDN's
// data sets) are in core/aov/conventions.h; besides them, any files given together whose names say what they
// hold (albedo/alb, normal/nrm, depth/z, variance, ref).
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/aov/aov_stack.h"

namespace residue {

struct FileSet {
  std::string convention;
  std::map<AovRole, std::filesystem::path> files;  // always has Color
  NormalSpace normal_space = NormalSpace::Unknown;  // what the convention's normal file holds
  DepthKind depth_kind = DepthKind::Unknown;        // and its depth file
};

// A folder given as input -> the colour file inside it, by the file-set conventions (Tungsten's color.exr, ...).
// Throws Error(Input) naming the folder and what was looked for when there is none, or several.
std::filesystem::path colour_file_in_folder(const std::filesystem::path& folder);

// The siblings of a single-layer colour file, by the first convention that claims it. Only existing files are
// listed.
FileSet sibling_file_set(const std::filesystem::path& colour_file);

// Roles of several files given together, by their names; the first file without a role keyword is colour.
// Throws Error(Input) when two files claim one role or none is colour.
FileSet file_set_from_names(const std::vector<std::filesystem::path>& files);

}  // namespace residue
