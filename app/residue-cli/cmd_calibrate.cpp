// residue-cli calibrate: measures what int8 inference needs of a model (core/nn/calibration.h): the largest
// |value| each op of its network takes while it denoises a data set's training scenes in fp32, written beside the
// model file (NAME.int8.json) unless -o says where. Validation scenes are never used.
#include <chrono>
#include <cstdio>

#include "cli_common.h"
#include "commands.h"
#include "core/aov/dataset.h"
#include "core/denoise/value_ranges.h"
#include "core/nn/calibration.h"
#include "core/nn/model_registry.h"

namespace residue::cli {
namespace {

struct CalibrateArgs {
  std::string model = nn::kDefaultModel;
  std::string set;
  size_t scenes = 0;  // 0: every training scene
  std::string output;
  int threads = 0;
  double percentile = 100;  // of each scene's |values|; 100: the largest
};

int run_calibrate(const CalibrateArgs& a) {
  const std::filesystem::path file = nn::find_model_for(a.model, FeatureSet::Full);
  const nn::Model model = nn::load_model(file);
  if (model.prior || model.albedo_prefilter || model.normal_prefilter)
    throw Error(ErrorKind::Usage, "model '" + a.model + "' runs other networks before its own; calibrating it is "
                                  "not supported (calibrate the networks it runs one by one)");
  const DatasetSplit split = split_dataset(a.set, 6);
  std::vector<std::filesystem::path> scenes = split.train;
  if (a.scenes > 0 && scenes.size() > a.scenes) scenes.resize(a.scenes);
  if (scenes.empty()) throw Error(ErrorKind::Input, "'" + a.set + "' has no training scenes to calibrate on");

  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<float> ranges = measure_value_ranges(
      model, scenes.size(), [&](size_t k) { return load_dataset_scene(scenes[k], /*with_reference=*/false); },
      a.percentile / 100.0, a.threads, [&](size_t k) {
        std::fprintf(stderr, "\rcalibrating %s: scene %zu of %zu (%s)", model.name.c_str(), k + 1, scenes.size(),
                     scenes[k].filename().c_str());
      });
  std::fprintf(stderr, "\n");

  nn::Calibration c;
  c.ranges = ranges;
  if (a.percentile < 100) {
    char text[96];
    std::snprintf(text, sizeof text, "%g th percentile of each scene's non-zero |value|, the largest over the scenes",
                  a.percentile);
    c.statistic = text;
  }
  c.set = std::to_string(scenes.size()) + " training scenes of " +
          std::filesystem::path(a.set).lexically_normal().filename().string() +
          (split.from_index ? " (its index.json split)" : " (all but its last 6)") + ", noisy_a, whole frames";
  const std::filesystem::path out = a.output.empty() ? nn::calibration_path(file) : std::filesystem::path(a.output);
  nn::write_calibration(out, model.graph, c);
  std::printf("%s: %s, %zu ops, in %.0f s -> %s\n", model.name.c_str(), c.set.c_str(), ranges.size(),
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), out.c_str());
  return kOk;
}

}  // namespace

Command add_calibrate_command(CLI::App& app) {
  auto a = std::make_shared<CalibrateArgs>();
  CLI::App* cmd = app.add_subcommand("calibrate", "Measure a model's value ranges for --precision int8 on a data set's "
                                                  "training scenes");
  cmd->add_option("set", a->set, "A data set (one folder per scene, as ../shared/datasets/cycles-starter)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("-m,--model", a->model, "The model (a name or a file)")->check(non_empty("a model name or file"));
  cmd->add_option("--scenes", a->scenes, "At most this many training scenes (0: all)");
  cmd->add_option("-o,--output", a->output, "Where to write it (default: NAME.int8.json beside the model file)")
      ->check(non_empty("a file"));
  cmd->add_option("--threads", a->threads, "Threads (0: every core)")->check(CLI::NonNegativeNumber);
  cmd->add_option("--percentile", a->percentile,
                  "Each value's range: this percentile of each scene's non-zero |values| (100: the largest)")
      ->check(CLI::Range(50.0, 100.0));
  return {cmd, [a] { return run_calibrate(*a); }};
}

}  // namespace residue::cli
