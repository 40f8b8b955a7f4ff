// residue-cli bench: time per megapixel of each model size x backend x precision x tile size on a synthetic
// render, as GFLOP/s and as a share of this CPU's fp32 ceiling measured by the same tool (an FMA loop).
#include <chrono>
#include <cstdio>
#include <thread>
#include <iostream>
#include <memory>
#include <random>
#include <filesystem>
#include <sstream>

#include <nlohmann/json.hpp>
#include <tbb/task_arena.h>

#include "cli_common.h"
#include "commands.h"
#include "core/denoise/denoise_job.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/value_ranges.h"
#include "core/nn/calibration.h"
#include "core/nn/model_alias.h"
#include "core/nn/model_card.h"
#include "core/nn/model_file.h"
#include "core/nn/model_registry.h"
#include "core/util/cpu_peak.h"
#include "core/util/error.h"

namespace residue::cli {
namespace {

struct BenchOptions {
  std::vector<std::string> models = {"4/32", "8/32", "8/64", "16/128"};
  std::vector<std::string> backends;
  std::vector<std::string> precisions = {"fp32", "bf16"};
  std::vector<int64_t> tiles = {256, 512};
  int64_t size = 512;
  int threads = 0;
  int repeat = 2;
  bool json = false;
  double cancel_after = 0;  // > 0: measure how long a cancel takes to stop a run, not the run
};

// BLOCKS/WIDTH: a random ResNet of that size; anything else: a model name or file (the full-AOV variant), e.g.
// "small" or "oidn" (OIDN's rt_hdr_alb_nrm).
nn::Model bench_model(const std::string& text) {
  if (text.find('/') == std::string::npos || std::filesystem::is_regular_file(text))
    return nn::load_model_for(text, FeatureSet::Full);
  nn::Architecture a;
  char slash = 0;
  std::istringstream in(text);
  // Bounds far above any network worth timing (the paper's is 16/128), so that a typo does not spend minutes
  // and gigabytes before failing.
  constexpr int kMaxBlocks = 256, kMaxWidth = 1024;
  if (!(in >> a.blocks >> slash >> a.width) || slash != '/' || !in.eof() || a.blocks <= 0 || a.width <= 0)
    throw Error(ErrorKind::Usage, "--models: expected BLOCKS/WIDTH such as 16/128 or a model name, got \"" + text + "\"");
  if (a.blocks > kMaxBlocks || a.width > kMaxWidth)
    throw Error(ErrorKind::Usage, "--models " + text + ": at most " + std::to_string(kMaxBlocks) + " blocks of width " +
                                      std::to_string(kMaxWidth));
  return nn::model_from_network(nn::random_network(a, 1), text);
}

// A synthetic render with every AOV: smooth shapes plus noise, no empty tiles.
AovStack synthetic_stack(int64_t n) {
  AovStack s;
  s.convention = "synthetic";
  s.color.image = Image(n, n, 3);
  s.albedo = Aov{Image(n, n, 3), {}, {}, 0};
  s.normal = Aov{Image(n, n, 3), {}, {}, 0};
  s.depth = Aov{Image(n, n, 1), {}, {}, 0};
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> noise(0.0f, 1.0f);
  for (int64_t y = 0; y < n; ++y)
    for (int64_t x = 0; x < n; ++x) {
      for (int c = 0; c < 3; ++c) {
        s.color.image.at(x, y, c) = 0.2f + 0.5f * noise(rng) * static_cast<float>((x / 32 + y / 32 + c) % 3);
        s.albedo->image.at(x, y, c) = 0.3f + 0.1f * static_cast<float>(c);
      }
      s.normal->image.at(x, y, 2) = 1.0f;
      s.depth->image.at(x, y) = 1.0f + static_cast<float>(x + y) / static_cast<float>(n);
    }
  s.data_window = {0, 0, n, n};
  s.display_width = s.display_height = n;
  return s;
}

// Tile 0 is the viewer's automatic tile: about half a second per tile at the model's benchmarked speed.
int64_t tile_for(int64_t tile, const nn::Model& model, nn::Precision precision, int64_t size) {
  if (tile > 0) return std::min(tile, size);
  const nn::ModelCard card = nn::model_card(model, model.name);  // its numbers: the whole ensemble's
  const double s_per_mp = card.seconds_per_mp(precision).value_or(card.gflop_per_mp / 50.0);
  return std::min(interactive_tile(model.graph, s_per_mp), size);
}

// int8's speed does not depend on the ranges it quantises by: a model without a calibration (a random-weight size,
// a shipped model before its NAME.int8.json) is given ranges measured on the bench's synthetic image, so that
// `--precisions int8` measures every model. Its output is not meant to be looked at (say so).
void calibrate_for_speed(nn::Model& model, const BenchOptions& o) {
  const bool calibrated = std::any_of(model.graph.ops().begin(), model.graph.ops().end(),
                                      [](const nn::GraphOp& op) { return op.range > 0; });
  if (calibrated || model.prior || model.albedo_prefilter || model.normal_prefilter) return;
  nn::Calibration c;
  c.set = "the bench's synthetic image (speed only)";
  c.ranges = measure_value_ranges(model, 1, [&](size_t) { return synthetic_stack(std::min<int64_t>(o.size, 256)); },
                                  1.0, o.threads);
  nn::apply_calibration(model.graph, c);
  model.int8_calibration = c.statistic + " over " + c.set;
  if (!o.json)
    std::fprintf(stderr, "bench: %s has no int8 calibration; its ranges were measured on the bench image, for its "
                         "speed only\n", model.name.c_str());
}

// Every model of --models, loaded before anything is measured, so that a bad one is reported at once.
std::vector<nn::Model> bench_models(const BenchOptions& o) {
  std::vector<nn::Model> models;
  const bool int8 = std::find(o.precisions.begin(), o.precisions.end(), "int8") != o.precisions.end();
  for (const auto& model_text : o.models) {
    models.push_back(bench_model(model_text));
    if (int8) calibrate_for_speed(models.back(), o);
  }
  return models;
}

// Every model x backend x precision x tile of the options as denoise options (eigen runs fp32 only), in order.
template <typename RunOne>
void for_each_config(const BenchOptions& o, const std::vector<nn::Model>& models, int threads, RunOne&& run_one) {
  const std::vector<std::string> backends = o.backends.empty() ? nn::available_backends() : o.backends;
  for (size_t m = 0; m < models.size(); ++m) {
    const std::string& model_text = o.models[m];
    const nn::Model& model = models[m];
    for (const auto& backend : backends)
      for (const auto& precision : o.precisions) {
        if (backend == "eigen" && precision != "fp32") continue;
        for (int64_t tile : o.tiles) {
          DenoiseOptions d;
          d.backend = backend;
          d.precision = nn::parse_precision(precision);
          d.tile = tile_for(tile, model, d.precision, o.size);
          d.threads = threads;
          d.skip_empty_tiles = false;
          run_one(model_text, model, precision, tile <= 0, d);
        }
      }
  }
}

// Starts a run as the viewer does (a DenoiseJob on a worker thread), cancels it after `after` seconds and
// returns how long it took to stop, with the tiles finished by then.
std::pair<double, DenoiseJob::Progress> time_to_stop(const AovStack& stack, const nn::Model& model,
                                                     const DenoiseOptions& d, double after) {
  DenoiseJob job(std::make_shared<const AovStack>(stack), std::make_shared<const nn::Model>(model), d);
  std::this_thread::sleep_for(std::chrono::duration<double>(after));
  const auto progress = job.progress();
  const auto t0 = std::chrono::steady_clock::now();
  job.cancel();
  job.wait();
  return {std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), progress};
}

int run_cancel(const BenchOptions& o) {
  const AovStack stack = synthetic_stack(o.size);
  nlohmann::json rows = nlohmann::json::array();
  if (!o.json) {
    std::printf("cancel %.1f s into a run of a %lldx%lld image, as the viewer's Cancel does\n\n", o.cancel_after,
                static_cast<long long>(o.size), static_cast<long long>(o.size));
    std::printf("| model | backend | precision | tile | tiles done | time to stop (s) |\n|---|---|---|---|---|---|\n");
  }
  const std::vector<nn::Model> models = bench_models(o);
  for_each_config(o, models, o.threads, [&](const std::string& model_text, const nn::Model& model, const std::string& precision,
                                    bool auto_tile, const DenoiseOptions& d) {
    const auto [stop, progress] = time_to_stop(stack, model, d, o.cancel_after);
    rows.push_back({{"model", model_text}, {"backend", d.backend}, {"precision", precision}, {"tile", d.tile},
                    {"auto_tile", auto_tile}, {"tiles_done", progress.done}, {"tiles", progress.total},
                    {"seconds_to_stop", stop}});
    if (!o.json)
      std::printf("| %s | %s | %s | %lld%s | %lld of %lld | %.2f |\n", model_text.c_str(), d.backend.c_str(),
                  precision.c_str(), static_cast<long long>(d.tile), auto_tile ? " (auto)" : "",
                  static_cast<long long>(progress.done), static_cast<long long>(progress.total), stop);
    std::fflush(stdout);
  });
  if (o.json)
    std::cout << nlohmann::json{{"cancel_after_seconds", o.cancel_after}, {"image", o.size}, {"rows", rows}}.dump(2)
              << "\n";
  return kOk;
}

int run(const BenchOptions& o) {
  if (o.cancel_after > 0) return run_cancel(o);
  const std::vector<nn::Model> models = bench_models(o);  // a bad model before the ceiling's seconds
  const int threads = o.threads > 0 ? o.threads : tbb::this_task_arena::max_concurrency();
  const CpuPeak peak = measure_fp32_peak(threads);
  const AovStack stack = synthetic_stack(o.size);
  const double megapixels = static_cast<double>(o.size * o.size) / 1e6;

  nlohmann::json rows = nlohmann::json::array();
  if (!o.json) {
    std::printf("%s; fp32 ceiling measured: %.0f GFLOP/s (%s FMA loop, %d threads); image %lldx%lld\n\n",
                cpu_description().c_str(), peak.gflops, peak.isa.c_str(), threads, static_cast<long long>(o.size),
                static_cast<long long>(o.size));
    std::printf("| model | backend | precision | tile | s / MP | GFLOP/s | %% of its peak | first run s / MP | "
                "implementation |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|\n");
  }
  for_each_config(o, models, threads, [&](const std::string& model_text, const nn::Model& model, const std::string& precision,
                                  bool, const DenoiseOptions& d) {
    // The first run is cold, as a one-off `residue-cli denoise` is: oneDNN's primitives are created and its
    // weights reordered, and the arena is faulted in. The timed runs after it reuse the backend, as the tiles
    // after the first and a viewer's next run do; the fastest of them counts.
    DenoiseStats first, best;
    best.seconds = 1e30;
    try {
      BackendCache cache;
      DenoiseOptions warm = d;
      warm.backends = &cache;
      denoise(stack, model, warm, {}, &first);
      for (int r = 0; r < o.repeat; ++r) {
        DenoiseStats st;
        denoise(stack, model, warm, {}, &st);
        if (st.seconds < best.seconds) best = st;
      }
    } catch (const Error& e) {
      std::fprintf(stderr, "bench: %s %s %s: %s\n", model_text.c_str(), d.backend.c_str(), precision.c_str(), e.what());
      return;
    }
    // Useful work (every member of a self-ensemble, any prefilter): the halo each tile recomputes is not counted.
    const double gflops = nn::model_card(model, model.name).gflop_per_mp * megapixels / best.seconds;
    // Against the precision's own ceiling: AVX512-BF16's dot product does two multiply-adds per fp32 lane,
    // AVX512-VNNI's vpdpbusd four.
    const double ceiling = peak.gflops * (d.precision == nn::Precision::BF16 ? 2.0 : d.precision == nn::Precision::INT8 ? 4.0 : 1.0);
    const double share = 100.0 * gflops / ceiling;
    rows.push_back({{"model", model_text}, {"backend", d.backend}, {"precision", precision}, {"tile", d.tile},
                    {"seconds_per_megapixel", best.seconds / megapixels}, {"gflops", gflops},
                    {"percent_of_fp32_peak", 100.0 * gflops / peak.gflops}, {"percent_of_peak", share},
                    {"peak_gflops", ceiling}, {"first_run_seconds_per_megapixel", first.seconds / megapixels},
                    {"implementation", best.backend}});
    if (!o.json)
      std::printf("| %s | %s | %s | %lld | %.3f | %.0f | %.0f %% | %.3f | %s |\n", model_text.c_str(),
                  d.backend.c_str(), precision.c_str(), static_cast<long long>(d.tile), best.seconds / megapixels,
                  gflops, share, first.seconds / megapixels, best.backend.c_str());
    std::fflush(stdout);
  });
  if (o.json)
    std::cout << nlohmann::json{{"cpu", cpu_description()}, {"fp32_peak_gflops", peak.gflops}, {"peak_isa", peak.isa},
                                {"threads", threads},
                                {"image", o.size}, {"rows", rows}}.dump(2)
              << "\n";
  if (rows.empty())
    throw Error(ErrorKind::Usage, "bench measured nothing: every configuration failed (above)");
  if (o.json) return kOk;
    std::printf("\nGFLOP/s counts the network's useful work (%s); the halo each tile recomputes is overhead.\n"
                "s / MP: the fastest of %d runs after a first, cold one (primitive creation, weight reorders, fresh "
                "arena pages), which is timed on its own.\n",
                "2 x multiply-adds per output pixel", o.repeat);
  std::printf("%% of its peak: of the fp32 ceiling measured above for fp32, of twice it for bf16 (AVX512-BF16's dot "
              "product does two multiply-adds per fp32 lane), of four times it for int8 (AVX512-VNNI's four).\n");
  return kOk;
}

}  // namespace

Command add_bench_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("bench", "Measure seconds per megapixel for model sizes, backends, precisions, tiles");
  auto o = std::make_shared<BenchOptions>();
  cmd->add_option("--models", o->models, "Model sizes BLOCKS/WIDTH (random weights) or model names (small, oidn, ...)")->capture_default_str()->delimiter(',');
  cmd->add_option("--backends", o->backends, "Backends (default: all available)")
      ->delimiter(',')
      ->check(CLI::IsMember(nn::available_backends()));
  cmd->add_option("--precisions", o->precisions, "fp32, bf16, int8 (a model without a calibration gets ranges measured on the bench image: its speed only)")
      ->capture_default_str()
      ->delimiter(',')
      ->check(CLI::IsMember(nn::precision_names()));
  cmd->add_option("--tiles", o->tiles, "Tile edges; 0 = the viewer's automatic tile")
      ->capture_default_str()
      ->delimiter(',')
      ->check(CLI::Range(int64_t{0}, int64_t{1} << 20));
  cmd->add_option("--size", o->size, "Edge of the square test image")->capture_default_str()->check(CLI::Range(16, 16384));
  cmd->add_option("--threads", o->threads, "Threads (default: every core)")->check(CLI::Range(1, 1024));
  cmd->add_option("--repeat", o->repeat, "Timed runs per configuration after the cold first one; the fastest counts")->capture_default_str()->check(CLI::Range(1, 100));
  cmd->add_flag("--json", o->json, "Print JSON instead of a Markdown table");
  cmd->add_option("--cancel-after", o->cancel_after,
                  "Instead of timing runs: cancel each S seconds in (as the viewer's Cancel) and time the stop")
      ->check(CLI::Range(0.0, 3600.0) & CLI::Validator([](std::string& v) {
        return v.find_first_of("nN") == std::string::npos ? std::string() : "must be a number of seconds, not '" + v + "'";
      }, "", "SECONDS"));
  return {cmd, [o]() { return run(*o); }};
}

}  // namespace residue::cli
