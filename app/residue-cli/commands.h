// The subcommands of residue-cli. Each registers itself on the app and returns a runner.
#pragma once

#include <functional>

#include <CLI/CLI.hpp>

namespace residue::cli {

// A registered subcommand and what runs it once the arguments are parsed; returns an ExitCode.
struct Command {
  CLI::App* app = nullptr;
  std::function<int()> run;
};

Command add_info_command(CLI::App& app);
Command add_eval_command(CLI::App& app);
Command add_denoise_command(CLI::App& app);
Command add_bench_command(CLI::App& app);
Command add_evaluate_set_command(CLI::App& app);
Command add_farm_command(CLI::App& app);
Command add_models_command(CLI::App& app);
Command add_calibrate_command(CLI::App& app);

}  // namespace residue::cli
