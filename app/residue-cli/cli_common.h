// What the residue-cli subcommands share: exit codes, input options (mapping flags), and formatting.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "core/aov/aov_loader.h"
#include "core/image/image.h"
#include "core/io/metrics_report.h"
#include "core/util/error.h"

namespace residue::cli {

// Exit codes mean the same thing for every subcommand.
enum ExitCode : int {
  kOk = 0,
  kInternalError = 1,  // a bug or an unexpected failure
  kUsageError = 2,     // bad arguments
  kInputError = 3,     // an input is missing, unreadable, or lacks what is needed
  kOutputError = 4,    // an output exists (no --force) or cannot be written
};

// The exit code for an error of this kind.
int exit_code_for(ErrorKind kind);

// Options that say how to read an AOV stack; added to every subcommand that reads one.
struct InputOptions {
  std::vector<std::string> inputs;
  std::vector<std::string> map_flags;
  std::string mapping_file;
  std::string layer;
  std::string reference;
  std::string normal_space;

  void add_to(CLI::App& app, bool with_reference);
  LoadOptions load_options() const;
  AovStack load() const;
  // Every file these options name as something to read (inputs, reference, mapping file, --map files), for
  // checking that no output replaces one of them.
  std::vector<std::filesystem::path> files_named() const;
};

// CLI11 validators for what its own do not refuse: an option given as "" (which would read as not given), and
// a number that must be finite and > 0 (CLI::PositiveNumber lets NaN through).
CLI::Validator non_empty(const std::string& expected);
CLI::Validator positive_finite();
// "on" / "off" into a bool: the option's value is typed, and anything else is refused listing the two.
CLI::Option* add_on_off(CLI::App* cmd, const std::string& name, bool& value, const std::string& help);
inline const char* on_off(bool value) { return value ? "on" : "off"; }

// "x,y,w,h" -> Rect; throws CLI::ValidationError on a malformed one.
Rect parse_roi(const std::string& text);

// The metrics table residue-cli prints (eval, denoise), with the formula under it.
void print_metrics_table(const io::MetricsReport& report);

// A path relative to the current folder when that is shorter, for tidy tables.
std::string display_path(const std::string& path);

}  // namespace residue::cli
