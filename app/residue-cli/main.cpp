// residue-cli: the command-line face of Residue. Subcommands live in cmd_*.cpp; exit codes in cli_common.h.
#include <cstdio>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli_common.h"
#include "commands.h"
#include "core/util/error.h"
#include "core/util/openmp_env.h"

int main(int argc, char** argv) {
  residue::ensure_passive_openmp(argc, argv);  // first: may re-execute the program (see openmp_env.h)
  using namespace residue::cli;
  CLI::App app{"Residue: denoise Monte Carlo renders with a direct residual network, and judge the result",
               "residue-cli"};
  app.set_version_flag("--version", std::string("residue-cli ") + RESIDUE_VERSION);
  app.require_subcommand(1);
  const std::vector<Command> commands = {add_info_command(app), add_eval_command(app), add_denoise_command(app), add_bench_command(app), add_evaluate_set_command(app), add_farm_command(app), add_models_command(app), add_calibrate_command(app)};

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kOk : kUsageError;
  }
  try {
    for (const Command& c : commands)
      if (c.app->parsed()) return c.run();
    return kUsageError;
  } catch (const CLI::ParseError& e) {  // validation inside a runner (e.g. --roi)
    std::fprintf(stderr, "residue-cli: %s\n", e.what());
    return kUsageError;
  } catch (const residue::Error& e) {
    std::fprintf(stderr, "residue-cli: error: %s\n", e.what());
    return exit_code_for(e.kind());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "residue-cli: internal error: %s\n", e.what());
    return kInternalError;
  }
}
