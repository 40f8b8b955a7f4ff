// Single-AOV file sets: renders that write one file per buffer.
//   Tungsten        color.exr, albedo.exr, normal.exr, depth.exr, colorVariance.exr (+ reference.exr)
//   OIDN data sets  NAME_0016spp.hdr.exr, NAME_0016spp.alb.exr, NAME_0016spp.nrm.exr, NAME_0016spp.z.exr,
//                   reference NAME_ref.hdr.exr
//   any files given together whose names say what they hold (albedo/alb, normal/nrm, depth/z, variance, ref).
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
};

// A folder given as input -> the colour file inside it (Tungsten's color.exr, an OIDN *spp.hdr.exr).
// Throws Error(Input) naming the folder and what was looked for when there is none, or several.
std::filesystem::path colour_file_in_folder(const std::filesystem::path& folder);

// The siblings of a single-layer colour file, by the conventions above. Only existing files are listed.
FileSet sibling_file_set(const std::filesystem::path& colour_file);

// Roles of several files given together, by their names; the first file without a role keyword is colour.
// Throws Error(Input) when two files claim one role or none is colour.
FileSet file_set_from_names(const std::vector<std::filesystem::path>& files);

}  // namespace residue
