// residue-cli evaluate-set: runs models over a data set's scenes and writes one table (scene x model: relMSE,
// SSIM, time) as Markdown and JSON: the measured speed/accuracy trade users pick from.
#include <chrono>
#include <cmath>
#include <random>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>

#include "cli_common.h"
#include "app/common/cli_enum.h"
#include "commands.h"
#include "core/aov/dataset.h"
#include "core/denoise/method_registry.h"
#include "core/denoise/denoiser.h"
#include "core/features/features.h"
#include "core/io/atomic_file.h"
#include "core/metrics/flip.h"
#include "core/metrics/metrics.h"
#include "core/nn/model_alias.h"
#include "core/nn/model_card.h"
#include "core/util/error.h"

namespace residue::cli {
namespace {

struct EvalSetOptions {
  std::string dataset;
  std::vector<std::string> models;
  std::vector<std::string> precisions = {"fp32"};
  std::vector<int> ensembles = {0};  // self-ensemble sizes; 0: each model's own
  std::string backend;
  int last = 0;  // 0: every scene
  std::string split = "all";  // or the data set's "train" / "validation" cut (index.json)
  std::string perturb = "none";  // input-convention studies: see perturb_inputs
  // The energy correction's columns: with it, without it ("raw"), or both for every model.
  enum class Energy { On, Off, Both } energy = Energy::On;
  bool variance_blend = true;  // with the data set's variance (from the two halves)
  bool output_guard = true;    // bound the network's output by its receptive field's max
  float blend_tau = 0;                // 0: each model's own (or the default)
  std::string out_md, out_json;
  int threads = 0;
  bool force = false;
  bool flip = true;  // HDR-FLIP beside relMSE and SSIM
};

struct Cell {
  double relmse = 0, ssim = 0, seconds = 0;
  double hdr_flip = 0;  // when o.flip
  double mean_ratio = 1;  // mean of the output over the mean of the reference (brightness bias)
  int64_t guarded = 0;    // output values the guard clamped
  bool energy_corrected = false;  // the energy correction ran (Residue's networks, when on)
};

// Changes a scene's AOVs the way another renderer's conventions would, to measure what the models make of
// it: "normals-world" turns the normals by a random rotation (world-space normals with no camera, taken as
// view space), "normals-zero" removes their information, "depth-x100" changes depth units (cm for m),
// "no-variance" drops the variance AOV.
void perturb_inputs(AovStack& s, const std::string& mode, unsigned seed) {
  if (mode == "none") return;
  if (mode == "no-variance") {
    s.variance.reset();
  } else if (mode == "depth-x100") {
    if (s.depth) for (size_t i = 0; i < s.depth->image.size(); ++i) s.depth->image.data()[i] *= 100.0f;
  } else if (mode == "normals-zero" || mode == "normals-world") {
    if (!s.normal) return;
    double r[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    if (mode == "normals-world") {
      // A uniformly random rotation from a random unit quaternion.
      std::mt19937 rng(seed);
      std::normal_distribution<double> g;
      double q[4], n = 0;
      for (double& v : q) {
        v = g(rng);
        n += v * v;
      }
      n = std::sqrt(n);
      const double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
      const double m[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                           2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                           2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)};
      std::copy(m, m + 9, r);
    }
    Image& im = s.normal->image;
    for (int64_t i = 0; i < im.pixel_count(); ++i) {
      float* v = im.data() + i * im.channels();
      const double a = v[0], b = v[1], c = v[2];
      for (int k = 0; k < 3; ++k) v[k] = static_cast<float>(r[3 * k] * a + r[3 * k + 1] * b + r[3 * k + 2] * c);
    }
  } else {
    throw Error(ErrorKind::Usage, "--perturb: unknown mode '" + mode + "'");
  }
}

double mean_ratio(const Image& out, const Image& ref) {
  double so = 0, sr = 0;
  for (int64_t y = 0; y < out.height(); ++y)
    for (int64_t x = 0; x < out.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        const double o = out.at(x, y, c), r = ref.at(x, y, c);
        if (std::isfinite(o) && std::isfinite(r)) so += o, sr += r;
      }
  return sr > 0 ? so / sr : 1.0;
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

// Every check on the --md and --json outputs, before any model runs: their names, that neither is a file of
// the data set (its index.json, a scene's files), and prepare_output's.
void check_outputs(const EvalSetOptions& o, const std::vector<std::filesystem::path>& scenes) {
  std::vector<std::filesystem::path> read = {std::filesystem::path(o.dataset) / "index.json"};
  for (const auto& scene : scenes) {
    std::error_code ec;
    for (std::filesystem::directory_iterator it(scene, ec), end; !ec && it != end; it.increment(ec))
      read.push_back(it->path());
  }
  const std::pair<const std::string*, const char*> outputs[] = {{&o.out_md, "--md"}, {&o.out_json, "--json"}};
  for (const auto& [path, option] : outputs) {
    if (path->empty()) continue;
    io::require_extension(*path, {std::string(option) == "--md" ? ".md" : ".json"}, option);
    io::refuse_input_as_output(*path, read, option);
    io::prepare_output(*path, o.force);
  }
}

int run(const EvalSetOptions& o) {
  std::vector<std::filesystem::path> scenes = list_dataset_scenes(o.dataset);
  if (o.split != "all") {
    const DatasetSplit split = split_dataset(o.dataset, 0);
    if (!split.from_index)
      throw Error(ErrorKind::Usage, "--split " + o.split + ": '" + o.dataset + "' has no index.json; use --last N");
    scenes = o.split == "validation" ? split.validation : split.train;
  }
  if (o.last > 0 && static_cast<size_t>(o.last) < scenes.size())
    scenes.erase(scenes.begin(), scenes.end() - o.last);
  if (scenes.empty()) throw Error(ErrorKind::Input, "no scenes in '" + o.dataset + "'");
  check_outputs(o, scenes);

  struct Column {
    std::string label, model, precision;
    bool energy_correction = true;
    int ensemble = 0;
    bool network() const { return !model.empty() && !is_model_free_method(model); }  // not the input or a filter
  };
  std::vector<Column> columns = {{"noisy", "", ""}};
  for (const auto& m : o.models) {
    // A file is labelled by its stem, a model name by itself.
    const std::string label = std::filesystem::is_regular_file(m) ? std::filesystem::path(m).stem().string() : m;
    if (is_model_free_method(m)) {  // a filter (the baseline): no network, no precision
      columns.push_back({label, m, "fp32"});
      continue;
    }
    for (const auto& p : o.precisions)
      for (const int n : o.ensembles) {
        const std::string name = (o.precisions.size() > 1 ? label + " " + p : label) + (n > 0 ? " x" + std::to_string(n) : "");
        using Energy = EvalSetOptions::Energy;
        if (o.energy != Energy::Off) columns.push_back({name, m, p, true, n});
        if (o.energy != Energy::On) columns.push_back({o.energy == Energy::Both ? name + " raw" : name, m, p, false, n});
      }
  }

  // results[scene][column]
  std::vector<std::vector<Cell>> results(scenes.size(), std::vector<Cell>(columns.size()));
  nlohmann::json json_scenes = nlohmann::json::array();
  double megapixels_total = 0;
  nn::ModelRegistry models;
  for (size_t si = 0; si < scenes.size(); ++si) {
    AovStack stack = load_dataset_scene(scenes[si]);
    perturb_inputs(stack, o.perturb, static_cast<unsigned>(si) + 1);
    const double mp = static_cast<double>(stack.width() * stack.height()) / 1e6;
    megapixels_total += mp;
    nlohmann::json js = {{"scene", scenes[si].filename().string()}, {"megapixels", mp}};
    for (size_t ci = 0; ci < columns.size(); ++ci) {
      Cell& cell = results[si][ci];
      Image out;
      std::string model_file;
      if (columns[ci].model.empty()) {
        out = stack.color.image;
      } else {
        // Each model file is loaded once for every scene (a scene's AOVs may pick another variant).
        const std::unique_ptr<Method> method = resolve_method(columns[ci].model, feature_set_for(stack), models);
        if (method->model()) model_file = method->model()->path;
        DenoiseOptions d;
        d.backend = o.backend;
        d.precision = nn::parse_precision(columns[ci].precision);
        d.threads = o.threads;
        d.energy_correction = columns[ci].energy_correction;
        d.variance_blend = o.variance_blend;
        d.output_guard = o.output_guard;
        d.blend_tau = o.blend_tau;
        d.ensemble = columns[ci].ensemble;
        DenoiseStats st;
        out = denoise(stack, *method, d, {}, &st);
        cell.seconds = st.seconds;
        cell.guarded = st.guarded_values;
        cell.energy_corrected = st.energy_corrected;  // what ran: OIDN's networks take no post-steps
      }
      const auto s = metrics::compare(out, stack.reference->image);
      cell.relmse = s.relmse;
      cell.ssim = s.ssim;
      cell.mean_ratio = mean_ratio(out, stack.reference->image);
      js["results"][columns[ci].label] = {{"relmse", s.relmse}, {"ssim", s.ssim}, {"seconds", cell.seconds},
                                         {"mean_ratio", cell.mean_ratio}, {"model_file", model_file}, {"guarded_values", cell.guarded},
                                         {"energy_correction", cell.energy_corrected}};
      if (o.flip) {
        const metrics::FlipResult f = metrics::hdr_flip(out, stack.reference->image);
        cell.hdr_flip = f.mean;
        js["results"][columns[ci].label]["hdr_flip"] = cell.hdr_flip;
        js["flip_exposures"] = {{"start", f.exposures.start}, {"stop", f.exposures.stop}, {"count", f.exposures.count}};
      }
    }
    json_scenes.push_back(js);
    std::fprintf(stderr, "evaluate-set: %zu/%zu %s\n", si + 1, scenes.size(), scenes[si].filename().string().c_str());
  }

  // Markdown: one row per scene, then the means.
  std::ostringstream md;
  md << "| scene |";
  for (const auto& c : columns)
    md << " " << c.label << " relMSE | " << c.label << " SSIM |" << (o.flip ? " " + c.label + " FLIP |" : "")
       << (c.model.empty() ? "" : " " + c.label + " s |");
  md << "\n|---|";
  for (const auto& c : columns) md << "---|---|" << (o.flip ? "---|" : "") << (c.model.empty() ? "" : "---|");
  md << "\n";
  std::vector<Cell> mean(columns.size());
  for (auto& m : mean) m.mean_ratio = 0;
  for (size_t si = 0; si < scenes.size(); ++si) {
    md << "| " << scenes[si].filename().string() << " |";
    for (size_t ci = 0; ci < columns.size(); ++ci) {
      const Cell& c = results[si][ci];
      md << " " << fmt("%.4g", c.relmse) << " | " << fmt("%.4f", c.ssim) << " |"
         << (o.flip ? " " + fmt("%.4f", c.hdr_flip) + " |" : "")
         << (columns[ci].model.empty() ? "" : " " + fmt("%.2f", c.seconds) + " |");
      mean[ci].relmse += c.relmse / static_cast<double>(scenes.size());
      mean[ci].ssim += c.ssim / static_cast<double>(scenes.size());
      mean[ci].hdr_flip += c.hdr_flip / static_cast<double>(scenes.size());
      mean[ci].seconds += c.seconds;
      mean[ci].mean_ratio += c.mean_ratio / static_cast<double>(scenes.size());
      mean[ci].guarded += c.guarded;
    }
    md << "\n";
  }
  md << "| **mean** |";
  for (size_t ci = 0; ci < columns.size(); ++ci)
    md << " **" << fmt("%.4g", mean[ci].relmse) << "** | **" << fmt("%.4f", mean[ci].ssim) << "** |"
       << (o.flip ? " **" + fmt("%.4f", mean[ci].hdr_flip) + "** |" : "")
       << (columns[ci].model.empty() ? "" : " " + fmt("%.2f", mean[ci].seconds / megapixels_total) + " s/MP |");
  md << "\n\nMean brightness ratio (output / reference, 1 = unbiased):";
  for (size_t ci = 0; ci < columns.size(); ++ci) md << " " << columns[ci].label << " " << fmt("%.4f", mean[ci].mean_ratio);
  md << "\n\nOutput values clamped by the guard (all scenes):";
  for (size_t ci = 0; ci < columns.size(); ++ci)
    if (columns[ci].network()) md << " " << columns[ci].label << " " << mean[ci].guarded;
  if (o.perturb != "none") md << "\n\nInputs perturbed: " << o.perturb;
  md << "\n";

  nlohmann::json summary = nlohmann::json::array();
  for (size_t ci = 0; ci < columns.size(); ++ci) {
    summary.push_back({{"label", columns[ci].label}, {"model", columns[ci].model}, {"precision", columns[ci].precision},
                       {"ensemble", columns[ci].ensemble},
                       {"mean_relmse", mean[ci].relmse}, {"mean_ssim", mean[ci].ssim},
                       {"mean_ratio", mean[ci].mean_ratio},
                       {"relmse_reduction", mean[0].relmse / mean[ci].relmse},
                       {"seconds_per_megapixel", mean[ci].seconds / megapixels_total}});
    if (o.flip) summary.back()["mean_hdr_flip"] = mean[ci].hdr_flip;
  }
  const nlohmann::json j = {{"dataset", o.dataset}, {"split", o.split}, {"perturb", o.perturb}, {"variance_blend", on_off(o.variance_blend)}, {"output_guard", on_off(o.output_guard)}, {"blend_tau", o.blend_tau},
                            {"scenes", json_scenes}, {"summary", summary},
                            {"metrics", metrics::formula_text({})},
                            {"flip", o.flip ? "HDR-FLIP (core/metrics/flip.h) over each scene's flip_exposures, set by its reference"
                                            : "not computed (--flip off)"}};

  auto write_text = [&](const std::string& path, const std::string& text) {
    io::write_atomically(path, o.force, [&](const std::filesystem::path& tmp) {
      std::ofstream out(tmp);
      out << text;
      if (!out) throw Error(ErrorKind::Output, "cannot write '" + path + "'");
    });
  };
  if (!o.out_md.empty()) write_text(o.out_md, md.str());
  if (!o.out_json.empty()) write_text(o.out_json, j.dump(2) + "\n");
  std::cout << md.str();
  return kOk;
}

}  // namespace

Command add_evaluate_set_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("evaluate-set", "Run models over a data set; one table of relMSE, SSIM and time");
  auto o = std::make_shared<EvalSetOptions>();
  cmd->add_option("dataset", o->dataset, "Data set folder (s<seed>/noisy_a.exr, reference.exr)")->required();
  cmd->add_option("--models", o->models, "Model names or files; \"bilateral\" is the cross-bilateral baseline")->required()->delimiter(',');
  cmd->add_option("--precisions", o->precisions, "fp32, bf16")->capture_default_str()->delimiter(',')
      ->check(CLI::IsMember(nn::precision_names()));
  cmd->add_option("--ensembles", o->ensembles,
                  "Self-ensemble sizes, a column each (1, 2, 4, 8: the network under that many flips and transposes, "
                  "averaged; default: each model's own)")
      ->delimiter(',')
      ->check(CLI::IsMember({1, 2, 4, 8}));
  cmd->add_option("--backend", o->backend, "Inference backend (default: the faster here: eigen for fp32 on CPUs with AVX-512, else onednn)");
  cmd->add_option("--last", o->last, "Only the last N scenes by name (the starter set's validation scenes)")
      ->check(CLI::Range(1, 1 << 30));
  cmd->add_option("--perturb", o->perturb,
                  "Study other renderers' conventions: normals-world, normals-zero, depth-x100, no-variance")
      ->capture_default_str();
  cmd->add_option("--split", o->split, "all, or the data set's train / validation cut (its index.json)")
      ->capture_default_str()->check(CLI::IsMember({"all", "train", "validation"}));
  add_on_off(cmd, "--variance-blend", o->variance_blend,
             "on or off: keep clean input pixels, from the variance of the scenes' two halves");
  add_on_off(cmd, "--output-guard", o->output_guard,
             "on or off: clamp the network's output to its receptive field's brightest input (x2)");
  cmd->add_option("--blend-tau", o->blend_tau, "The variance blend's tau for every model (tools/models/fit_blend_tau.py)")
      ->check(positive_finite());
  using Energy = EvalSetOptions::Energy;
  add_enum_option<Energy>(cmd, "--energy-correction", o->energy, {{"on", Energy::On}, {"off", Energy::Off}, {"both", Energy::Both}},
                          "on, off, or both (a second column per model, labelled \"raw\", without the correction)");
  cmd->add_option("--md", o->out_md, "Write the table as Markdown");
  cmd->add_option("--json", o->out_json, "Write every number as JSON");
  cmd->add_option("--threads", o->threads, "Threads (default: every core)")->check(CLI::Range(1, 1024));
  add_on_off(cmd, "--flip", o->flip, "Score HDR-FLIP too (core/metrics/flip.h; about 2 s per megapixel on 2 cores)");
  cmd->add_flag("-f,--force", o->force, "Replace output files");
  return {cmd, [o]() { return run(*o); }};
}

}  // namespace residue::cli
