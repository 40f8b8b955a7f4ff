// residue-train: trains the paper's network on rendered scenes and exports a model file core loads.
//
//   residue-train --data DIR --val 6 --arch 4/32 --features full --steps 3000 --out tiny.safetensors
//
// Patches 64x64 (batch 8) sampled by noise, flips/rotations, L1 on log colour, Adam with gradient clipping at
// 1.0 and a cosine learning-rate decay; validation through core's own inference and metrics every K steps;
// checkpoints (resumed automatically) so a killed run goes on where it stopped.
#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <ATen/autocast_mode.h>
#include <torch/torch.h>

#include "core/aov/aov_loader.h"
#include "core/aov/dataset.h"
#include "core/aov/shot_dataset.h"
#include "core/denoise/denoiser.h"
#include "core/metrics/metrics.h"
#include "core/nn/calibration.h"
#include "core/nn/model_file.h"
#include "core/nn/model_registry.h"
#include "core/util/error.h"
#include "core/util/openmp_env.h"
#include "checkpoint.h"
#include "quantise.h"
#include "torch_network.h"
#include "app/common/cli_enum.h"
#include "training_loss.h"
#include "training_set.h"

namespace fs = std::filesystem;
using namespace residue;

namespace {

struct Options {
  std::vector<std::string> data;
  std::vector<std::string> shots;  // shot data sets (render_shots.py), for a temporal model
  int temporal = 0;                // the radius of the neighbouring frames a temporal model sees
  int val = 6;
  std::string arch = "4/32";
  std::string features = "full";
  std::string dilations;  // per ResBlock, repeated; empty: none (the paper)
  bool input_skip = false;  // variant: the network predicts the correction to the log noisy colour
  bool demodulate = false;  // variant: colour divided by the albedo in, multiplied back out
  bool autoexposure = false;  // variant: colour scaled by the image's autoexposure in, divided back out
  float exposure_key = nn::Architecture::kOidnExposureKey;  // what the autoexposure maps the log-average luminance to
  std::string prior;        // post-correction: refine this model's output ("oidn")
  std::string teacher;      // distillation: a model (name or file) whose output the targets move towards
  float teacher_weight = 0.5f;
  int teacher_ensemble = 8;
  int steps = 3000;
  int batch = 8;
  int patch = 64;
  double lr = 1e-3;
  int val_every = 500;
  std::string checkpoint;
  int checkpoint_every = 250;  // steps; validation also checkpoints
  std::string out;
  std::string name;
  std::string log;
  int threads = 2;
  uint32_t seed = 1;
  bool force = false;
  bool bf16 = false;  // CPU autocast: convolutions in bfloat16, weights, loss and optimiser in float
  train::Loss loss = train::Loss::L1Log;  // see training_loss.h
  double ssim_weight = 1.0;      // for l1-log+ssim and l1-pu+ssim
  double relmse_weight = 0.0;    // adds relmse_weight x relMSE (eps 0.01) to the loss
  double temporal_weight = 0.0;  // adds temporal_weight x L1 of the change between consecutive frames' errors
  double lowband_weight = 0.0;   // adds lowband_weight x the relMSE of lowband_width-px box means
  int lowband_width = 16;
  double edge_ssim_weight = 0.0;  // adds edge_ssim_weight x the albedo/normal edge pixels' share of 1 - SSIM
  int precise_bn = 0;            // batches for recalibrating BN statistics before validation and export; 0: off
  double freeze_bn_after = 1.0;  // fraction of the steps after which BN statistics are frozen; 1: never
  std::string init_from;         // a model file to start from (a fresh run only); empty: He initialisation
  std::string grow_from;         // a multi-scale model file one level shallower to start from (a fresh run only)
  std::string widen_from;        // a model file of the same architecture, narrower, to start from (a fresh run only)
  std::string export_set;        // write the loaded training and validation scenes to this file and stop
  std::string quantise;          // quantisation-aware fine-tuning of this model for int8 (quantise.h)
  double range_lr = 1e-3;        // --quantise: the log ranges' learning rate
  double range_init = 0.25;      // --quantise: the ranges' start, as a share of the largest values
  std::string range_start;       // --quantise: or the ranges of this calibration file
  std::string quantise_sensitivity;  // --quantise: instead of training, what each value's 8 bits cost (JSON)
};

struct Validation {
  double relmse = 0, ssim = 0, noisy_relmse = 0, noisy_ssim = 0, mean_ratio = 0;
  nlohmann::json per_scene = nlohmann::json::array();
};

// Denoises every validation scene with core (the shipped inference path) and scores it.
Validation validate(train::ResidueNet& net, const std::vector<train::TrainingSource>& scenes, const fs::path& tmp_model) {
  if (fs::exists(tmp_model)) fs::remove(tmp_model);
  nn::write_safetensors(tmp_model, train::export_model(net, {}), true);
  const nn::Model model = nn::load_model(tmp_model);
  Validation v;
  for (const train::TrainingSource& source : scenes) {
    const AovStack s = train::load_source(source, net->arch.temporal);
    DenoiseOptions d;
    d.skip_empty_tiles = false;
    const Image out = denoise(s, model, d);
    const auto den = metrics::compare(out, s.reference->image);
    const auto noisy = metrics::compare(s.color.image, s.reference->image);
    double sum_out = 0, sum_ref = 0;
    for (size_t i = 0; i < out.size(); ++i) {
      sum_out += out.data()[i];
      if (std::isfinite(s.reference->image.data()[i])) sum_ref += s.reference->image.data()[i];
    }
    const double ratio = sum_ref > 0 ? sum_out / sum_ref : 1.0;
    v.relmse += den.relmse;
    v.ssim += den.ssim;
    v.noisy_relmse += noisy.relmse;
    v.noisy_ssim += noisy.ssim;
    v.mean_ratio += ratio;
    v.per_scene.push_back({{"scene", source.name()}, {"noisy_relmse", noisy.relmse}, {"relmse", den.relmse},
                           {"noisy_ssim", noisy.ssim}, {"ssim", den.ssim}, {"mean_ratio", ratio}});
  }
  const double n = static_cast<double>(scenes.size());
  v.relmse /= n;
  v.ssim /= n;
  v.noisy_relmse /= n;
  v.noisy_ssim /= n;
  v.mean_ratio /= n;
  return v;
}

// A network that reaches past the patch sees, at every training pixel, the zero padding of both opposite sides of
// the patch; on a whole image a pixel near one border sees that border alone, a case it never trained on. A
// 4-level network (reach 120 px) trained on 64-px patches painted stripes down the right and bottom edges of 14
// of the 64 starter scenes; on 128-px patches, none (docs/research/MODELS_HISTORY.md, lever 2b). So the patch must exceed the
// reach; below twice the reach no pixel is free of every border, which whole images have in their interior.
void check_patch_covers_reach(const nn::Architecture& arch, int patch) {
  const int reach = arch.halo(), a = arch.alignment();
  const int enough = (reach / a + 1) * a;  // the smallest patch on the pooling grid beyond the reach
  if (patch <= reach)
    throw Error(ErrorKind::Usage, "--patch " + std::to_string(patch) + " is within the reach of " + arch.to_string() +
                                      " (" + std::to_string(reach) + " px each side): every training pixel would see "
                                      "both opposite borders of its patch, which no pixel of a larger image does; "
                                      "use --patch " + std::to_string(enough) + " or more");
  if (patch < 2 * reach)
    std::printf("residue-train: note: the %d-px patch is under twice the network's reach (%d px): no training pixel "
                "is clear of every border; --patch %d would also train the interior of larger images\n",
                patch, reach, (2 * reach + a - 1) / a * a);
}

// --export-training-set: the scenes exactly as this trainer sees them (feature planes, targets, patch weights),
// for tools/models/torch_train.py, which trains the same network with PyTorch where a GPU is lent (docs/research/MODELS_HISTORY.md, lever 7).
// The validation scenes go in whole, as inference sees them; the architecture and options in the metadata.
int export_training_set(const Options& o, const nn::Architecture& arch, const train::TrainingSet& set,
                        const std::vector<train::TrainingSource>& val_scenes, const nn::Model* prior) {
  nn::SafetensorsFile out;
  train::add_to_export(set, "train", out);
  if (!val_scenes.empty()) train::add_to_export(train::TrainingSet(val_scenes, arch, o.patch, prior), "val", out);
  out.metadata["arch"] = o.arch;
  out.metadata["features"] = o.features;
  out.metadata["feature_planes"] = nlohmann::json(nn::input_planes(arch)).dump();
  out.metadata["autoexposure"] = arch.autoexposure ? "1" : "0";
  if (arch.autoexposure) out.metadata["exposure_key"] = nn::exposure_key_string(arch.exposure_key);
  out.metadata["normal_plane"] = std::to_string(train::normal_plane(arch.features));
  out.metadata["patch"] = std::to_string(o.patch);
  out.metadata["data"] = nlohmann::json(o.data).dump();
  nn::write_safetensors(o.export_set, out, o.force);
  std::printf("wrote %s: %zu training, %zu validation scenes\n", o.export_set.c_str(), set.size(), val_scenes.size());
  return 0;
}

int run(const Options& o) {
  torch::set_num_threads(o.threads);
  torch::manual_seed(o.seed);
  nn::Architecture arch;
  const size_t slash = o.arch.find('/');
  const auto blocks = nn::parse_ints(o.arch.substr(0, slash), 1, 64);
  const auto widths = slash == std::string::npos ? std::nullopt : nn::parse_ints(o.arch.substr(slash + 1), 1, 4096);
  if (!blocks || !widths || blocks->size() != widths->size())
    throw Error(ErrorKind::Usage, "--arch: expected BLOCKS/WIDTH (e.g. 8/64), or per level BLOCKS,.../WIDTH,... for a "
                                  "multi-scale network (e.g. 2,2,4/32,48,64)");
  arch.blocks = blocks->front();
  arch.width = widths->front();
  if (blocks->size() > 1) {
    arch.levels = *blocks;
    arch.widths = *widths;
    if (o.patch % arch.alignment() != 0)
      throw Error(ErrorKind::Usage, "--patch must be a multiple of " + std::to_string(arch.alignment()) + " for " +
                                    std::to_string(blocks->size()) + " levels");
  }
  arch.features = *feature_set_from_string(o.features);
  arch.input_skip = o.input_skip;
  arch.demodulate = o.demodulate;
  arch.autoexposure = o.autoexposure;
  arch.exposure_key = o.exposure_key;
  if (!arch.autoexposure && o.exposure_key != nn::Architecture::kOidnExposureKey)
    throw Error(ErrorKind::Usage, "--exposure-key needs --autoexposure");
  arch.prior = o.prior;
  arch.temporal = o.temporal;
  if (arch.temporal > 0 && o.shots.empty()) throw Error(ErrorKind::Usage, "--temporal trains on shots: give --shots");
  if (o.data.empty() && o.shots.empty()) throw Error(ErrorKind::Usage, "give --data (scenes) or --shots (shots)");
  const int albedo_at = train::albedo_plane(arch.features);
  if (!o.dilations.empty()) {
    const auto d = nn::parse_dilations(o.dilations);
    if (!d) throw Error(ErrorKind::Usage, "--dilations: expected integers from 1 to 64, e.g. 1,2,4,8");
    arch.dilations = *d;
  }
  std::optional<nn::Model> to_quantise;
  std::vector<float> start_ranges;
  if (!o.quantise.empty()) {
    to_quantise = nn::load_model(nn::find_model_for(o.quantise, FeatureSet::Full));
    arch = to_quantise->network.arch;  // the model's own: --arch, --features and the variants do not apply
    if (!o.range_start.empty()) start_ranges = nn::read_calibration_file(o.range_start, to_quantise->graph).ranges;  // before the data loads
  }
  // --arch, --features, --dilations, --demodulate, --prior and --temporal together (the rules model files obey).
  if (const auto c = arch.contradiction()) throw Error(ErrorKind::Usage, "these options cannot go together: " + *c);
  const int normal_at = train::normal_plane(arch.features);
  if (o.edge_ssim_weight > 0 && (albedo_at < 0 || normal_at < 0))
    throw Error(ErrorKind::Usage, "--edge-ssim-weight needs a feature set with the albedo and the normal, not \"" +
                                  o.features + "\"");
  check_patch_covers_reach(arch, o.patch);
  if (!o.teacher.empty() && !(o.teacher_weight > 0))
    throw Error(ErrorKind::Usage, "--teacher-weight must be above 0 with --teacher (at 0 the targets are the "
                                  "reference's alone: leave --teacher out)");
  if (o.lowband_weight > 0 && o.lowband_width > o.patch)
    throw Error(ErrorKind::Usage, "--lowband-width (" + std::to_string(o.lowband_width) +
                                  " px) must fit the patch (--patch " + std::to_string(o.patch) + ")");
  if (o.temporal_weight > 0 && (o.shots.empty() || o.batch % 2 != 0))
    throw Error(ErrorKind::Usage, "--temporal-weight trains on pairs of consecutive frames: give --shots and an even --batch");
  if (o.out.empty() && o.export_set.empty()) throw Error(ErrorKind::Usage, "--out is required");
  if (!o.export_set.empty() && fs::exists(o.export_set) && !o.force)
    throw Error(ErrorKind::Output, "'" + o.export_set + "' exists; pass --force");
  if (fs::exists(o.out) && !o.force) throw Error(ErrorKind::Output, "output '" + o.out + "' exists; pass --force");

  // Scenes: each data folder's own cut (index.json) or, without one, its last `val` scenes by name.
  std::vector<train::TrainingSource> train_scenes, val_scenes;
  auto add = [](std::vector<train::TrainingSource>& to, const std::vector<train::TrainingSource>& from) {
    to.insert(to.end(), from.begin(), from.end());
  };
  for (const auto& d : o.data) {
    const DatasetSplit split = split_dataset(d, static_cast<size_t>(o.val));
    add(train_scenes, train::scene_sources(split.train));
    add(val_scenes, train::scene_sources(split.validation));
    std::printf("residue-train: %s: %zu training, %zu validation scenes (%s)\n", d.c_str(), split.train.size(),
                split.validation.size(), split.from_index ? "index.json" : "the last by name");
  }
  for (const auto& d : o.shots) {  // every frame of a shot is a scene (with its neighbours, for a temporal model)
    const ShotSplit split = split_shots(d);
    const auto train = train::shot_sources(split.train), val = train::shot_sources(split.validation);
    add(train_scenes, train);
    add(val_scenes, val);
    std::printf("residue-train: %s: %zu training shots (%zu frames), %zu validation shots (%zu frames)\n", d.c_str(),
                split.train.size(), train.size(), split.validation.size(), val.size());
  }
  if (train_scenes.empty()) throw Error(ErrorKind::Input, "no scenes found in --data");
  std::printf("residue-train: %s, %zu training scenes, %zu validation scenes\n", arch.to_string().c_str(),
              train_scenes.size(), val_scenes.size());
  const auto t_load = std::chrono::steady_clock::now();
  std::optional<nn::Model> prior;
  if (!arch.prior.empty()) prior = nn::load_model(nn::find_model_for(arch.prior, FeatureSet::Full));
  std::optional<nn::Model> teacher;
  if (!o.teacher.empty()) teacher = nn::load_model(nn::find_model_for(o.teacher, FeatureSet::Full));
  const train::TrainingSet set(train_scenes, arch, o.patch, prior ? &*prior : nullptr,
                               {teacher ? &*teacher : nullptr, o.teacher_weight, o.teacher_ensemble});
  std::printf("loaded in %.1f s\n", std::chrono::duration<double>(std::chrono::steady_clock::now() - t_load).count());
  if (!o.export_set.empty()) return export_training_set(o, arch, set, val_scenes, prior ? &*prior : nullptr);
  if (to_quantise) {
    train::QuantiseOptions q;
    q.steps = o.steps;
    q.batch = o.batch;
    q.lr = o.lr;
    q.range_lr = o.range_lr;
    q.range_init = o.range_init;
    q.range_start = o.range_start;
    q.start_ranges = start_ranges;
    q.sensitivity = o.quantise_sensitivity;
    q.loss = o.loss;
    q.ssim_weight = o.ssim_weight;
    q.relmse_weight = o.relmse_weight;
    q.val_every = o.val_every;
    q.checkpoint_every = o.checkpoint_every;
    q.seed = o.seed;
    q.threads = o.threads;
    q.out = o.out;
    q.checkpoint = o.checkpoint;
    q.log = o.log;
    q.name = o.name;
    q.force = o.force;
    q.data = nlohmann::json(o.data).dump() + (teacher ? ", targets distilled from " + o.teacher : "");
    return train::quantise(*to_quantise, set, val_scenes, q);
  }

  // Input batches for batch-norm statistics, drawn as training draws them.
  auto input_batches = [&set, &o](std::mt19937& rng) {
    return [&set, &o, &rng] {
      torch::Tensor x, y;
      set.sample(rng, o.batch, x, y);
      return train::to_channels_last(x);
    };
  };
  train::ResidueNet net(arch);
  train::initialise(net);
  const fs::path ckpt = o.checkpoint.empty() ? fs::path(o.out).replace_extension(".ckpt") : fs::path(o.checkpoint);
  const bool resuming = fs::exists(ckpt / "step");
  const fs::path start_file = !o.init_from.empty() ? o.init_from : !o.grow_from.empty() ? o.grow_from : o.widen_from;
  std::string init_from_name;  // for the metadata
  if (!start_file.empty()) {
    const nn::SafetensorsFile source = nn::read_safetensors(start_file);
    const auto name = source.metadata.find("name");
    init_from_name = name != source.metadata.end() ? name->second : start_file.stem().string();
    // A resumed run's statistics come from its checkpoint: no batches to measure them over.
    std::mt19937 bn_rng(o.seed * 104729u);
    if (!o.grow_from.empty()) {
      train::grow_from(net, source, start_file, input_batches(bn_rng), resuming ? 0 : 100);
      init_from_name += ", grown by one level";
    } else if (!o.widen_from.empty()) {
      train::widen_from(net, source, start_file, input_batches(bn_rng), resuming ? 0 : 100);
      init_from_name += ", widened";
    } else {
      train::initialise_from(net, source, start_file);
    }
  }
  torch::optim::Adam opt(net->parameters(), torch::optim::AdamOptions(o.lr).betas({0.9, 0.999}));
  int step = 0;
  double wall_before = 0;  // training time of earlier runs of this model
  if (resuming) {
    step = train::load_checkpoint(ckpt, net, opt, &wall_before);
    std::printf("resumed from %s at step %d (%.0f s of training before)\n", ckpt.string().c_str(), step, wall_before);
  } else if (!init_from_name.empty()) {
    std::printf("initialised from %s (%s)\n", start_file.string().c_str(), init_from_name.c_str());
  }
  train::use_channels_last(net);  // after any loading, which may set the stored layout
  std::ofstream log;
  if (!o.log.empty()) {
    const bool fresh = !fs::exists(o.log) || step == 0;
    log.open(o.log, fresh ? std::ios::trunc : std::ios::app);
    if (fresh) log << "step,loss,lr,seconds_per_step,val_relmse,val_ssim,val_noisy_relmse,val_mean_ratio\n";
  }

  std::mt19937 rng(o.seed + static_cast<uint32_t>(step));  // a resumed run draws fresh patches
  const fs::path tmp_model = fs::path(ckpt) / "validation.safetensors";
  fs::create_directories(ckpt);
  const auto t_start = std::chrono::steady_clock::now();
  auto wall_total = [&] { return wall_before + std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count(); };
  double loss_sum = 0;
  int loss_n = 0;
  auto t_last = std::chrono::steady_clock::now();
  Validation last_val;
  bool validated = false;  // in this run
  const int freeze_step = static_cast<int>(std::lround(o.freeze_bn_after * o.steps));
  auto frozen = [&] { return step >= freeze_step && o.freeze_bn_after < 1.0; };
  auto recalibrate = [&] {
    if (o.precise_bn <= 0) return;
    if (frozen() && step > freeze_step) return;  // the statistics were fixed at freeze_step and trained with
    std::mt19937 bn_rng(o.seed * 7919u + static_cast<uint32_t>(step));
    train::recalibrate_batch_norm(net, input_batches(bn_rng), o.precise_bn);
  };
  // Each validation's per-scene numbers go to LOG.scenes.jsonl (one line per validation), so that a spike in
  // the mean can be traced to the scene that caused it.
  std::ofstream scene_log;
  if (!o.log.empty()) scene_log.open(o.log + ".scenes.jsonl", step == 0 ? std::ios::trunc : std::ios::app);
  auto run_validation = [&] {
    recalibrate();
    net->eval();
    torch::NoGradGuard no_grad;
    last_val = validate(net, val_scenes, tmp_model);
    validated = true;
    if (scene_log.is_open())
      scene_log << nlohmann::json{{"step", step}, {"relmse", last_val.relmse}, {"ssim", last_val.ssim},
                                  {"per_scene", last_val.per_scene}}.dump()
                << "\n" << std::flush;
  };
  while (step < o.steps) {
    const double lr = train::cosine_learning_rate(o.lr, step, o.steps);
    for (auto& g : opt.param_groups()) static_cast<torch::optim::AdamOptions&>(g.options()).lr(lr);

    if (step == freeze_step && frozen()) recalibrate();  // freeze the best statistics there are
    net->train();
    if (frozen()) train::freeze_batch_norm(net);
    torch::Tensor x, y;
    if (o.temporal_weight > 0) set.sample_pairs(rng, o.batch / 2, x, y);  // frame t, then the same patches of t - 1
    else set.sample(rng, o.batch, x, y);
    x = train::to_channels_last(x);
    opt.zero_grad();
    torch::Tensor prediction;
    if (o.bf16) {
      at::autocast::set_cpu_enabled(true);
      at::autocast::set_autocast_cpu_dtype(at::kBFloat16);
      prediction = net->forward(x).to(torch::kFloat32);
      at::autocast::set_cpu_enabled(false);
      at::autocast::clear_cache();
    } else {
      prediction = net->forward(x);
    }
    if (arch.demodulate) prediction = train::remodulate(prediction, x.slice(1, albedo_at, albedo_at + 3));
    torch::Tensor loss = train::training_loss(o.loss, prediction, y, o.ssim_weight);
    if (o.relmse_weight > 0) loss = loss + o.relmse_weight * train::relative_mse(prediction, y);
    if (o.temporal_weight > 0) {
      // The error's change from frame t - 1 to t at each pixel (in log colour), as the flicker metric sees it.
      const int64_t pairs = prediction.size(0) / 2;
      const torch::Tensor error = prediction - y;
      loss = loss + o.temporal_weight * (error.slice(0, 0, pairs) - error.slice(0, pairs)).abs().mean();
    }
    if (o.lowband_weight > 0)
      loss = loss + o.lowband_weight * train::low_band_relative_mse(prediction, y, o.lowband_width);
    if (o.edge_ssim_weight > 0) {
      const auto edges =
          train::aov_edge_mask(x.slice(1, albedo_at, albedo_at + 3), x.slice(1, normal_at, normal_at + 2));
      loss = loss + o.edge_ssim_weight * train::edge_ssim_loss(prediction, y, edges);
    }
    loss.backward();
    torch::nn::utils::clip_grad_norm_(net->parameters(), 1.0);
    opt.step();
    loss_sum += loss.item<double>();
    ++loss_n;
    ++step;

    const bool report = step % 50 == 0 || step % o.checkpoint_every == 0 || step == o.steps;
    const bool do_val = !val_scenes.empty() && (step % o.val_every == 0 || step == o.steps);
    if (report || do_val) {
      const double sps = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_last).count() / loss_n;
      std::string val_cols = ",,,";
      if (do_val) {
        run_validation();
        val_cols = std::to_string(last_val.relmse) + "," + std::to_string(last_val.ssim) + "," +
                   std::to_string(last_val.noisy_relmse) + "," + std::to_string(last_val.mean_ratio);
      }
      if (do_val || step % o.checkpoint_every == 0) train::save_checkpoint(ckpt, net, opt, step, wall_total());
      std::printf("step %6d  loss %.5f  lr %.2e  %.3f s/step%s\n", step, loss_sum / loss_n, lr, sps,
                  do_val ? ("  val relMSE " + std::to_string(last_val.relmse) + " (noisy " +
                            std::to_string(last_val.noisy_relmse) + ") SSIM " + std::to_string(last_val.ssim) +
                            " mean ratio " + std::to_string(last_val.mean_ratio))
                               .c_str()
                         : "");
      std::fflush(stdout);
      if (log.is_open()) log << step << "," << loss_sum / loss_n << "," << lr << "," << sps << "," << val_cols << "\n" << std::flush;
      loss_sum = 0;
      loss_n = 0;
      t_last = std::chrono::steady_clock::now();
    }
  }

  if (!validated) {  // no validation scenes, or a finished checkpoint exported again (e.g. with --precise-bn)
    if (val_scenes.empty()) {
      recalibrate();
    } else {
      run_validation();
      std::printf("step %6d  val relMSE %f SSIM %f mean ratio %f\n", step, last_val.relmse, last_val.ssim, last_val.mean_ratio);
    }
  }
  net->eval();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  const std::string loss_text =
      std::string(train::loss_kind(o.loss).description) + (o.relmse_weight > 0 ? " + w * relMSE (eps 0.01)" : "") +
      (o.lowband_weight > 0 ? " + w * relMSE of " + std::to_string(o.lowband_width) + "-px box means" : "") +
      (o.edge_ssim_weight > 0 ? " + w * (1 - SSIM) on albedo/normal edge pixels" : "") +
      (o.temporal_weight > 0 ? " + w * L1 of the change of the log error from frame t - 1 to t" : "") +
      (teacher ? ", against targets distilled from a teacher" : "");
  nlohmann::json training = {{"data", o.data}, {"shots", o.shots}, {"train_scenes", train_scenes.size()}, {"steps", o.steps},
                             {"batch", o.batch}, {"patch", o.patch}, {"lr", o.lr}, {"schedule", "cosine to lr/100, 100 warm-up"},
                             {"loss", loss_text}, {"optimizer", "Adam(0.9, 0.999), grad clip 1.0"},
                             {"seed", o.seed}, {"threads", o.threads}, {"wall_s_this_run", wall},
                             {"wall_s", wall_before + wall},
                             {"precision", o.bf16 ? "bf16 autocast" : "fp32"}, {"features", o.features},
                             {"precise_bn_batches", o.precise_bn}, {"freeze_bn_after", o.freeze_bn_after}};
  if (!init_from_name.empty()) training["init_from"] = init_from_name;
  if (train::loss_kind(o.loss).ssim_term) training["ssim_weight"] = o.ssim_weight;
  if (o.relmse_weight > 0) training["relmse_weight"] = o.relmse_weight;
  if (o.temporal_weight > 0) training["temporal_weight"] = o.temporal_weight;
  if (o.lowband_weight > 0) {
    training["lowband_weight"] = o.lowband_weight;
    training["lowband_width"] = o.lowband_width;
  }
  if (o.edge_ssim_weight > 0) training["edge_ssim_weight"] = o.edge_ssim_weight;
  if (teacher)
    training["teacher"] = {{"model", o.teacher}, {"weight", o.teacher_weight}, {"ensemble", o.teacher_ensemble},
                           {"target", "(1 - weight) log(1 + reference) + weight log(1 + teacher's output)"}};
  nlohmann::json validation = {{"scenes", val_scenes.size()}, {"relmse", last_val.relmse}, {"ssim", last_val.ssim},
                               {"noisy_relmse", last_val.noisy_relmse}, {"noisy_ssim", last_val.noisy_ssim},
                               {"mean_ratio", last_val.mean_ratio}, {"per_scene", last_val.per_scene}};
  std::map<std::string, std::string> md = {{"name", o.name.empty() ? fs::path(o.out).stem().string() : o.name},
                                           {"training", training.dump()}, {"validation", validation.dump()}};
  nn::write_safetensors(o.out, train::export_model(net, md), o.force);
  std::printf("wrote %s\n", o.out.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  ensure_passive_openmp(argc, argv);
  CLI::App app{"residue-train: train the residual denoising network and export a model file", "residue-train"};
  Options o;
  app.add_option("--data", o.data, "Data set folders (s<seed>/noisy_a.exr, noisy_b.exr, reference.exr)");
  app.add_option("--shots", o.shots, "Shot data set folders (tools/datagen/render_shots.py: s<seed>/noisy.####.exr, "
                 "reference.####.exr, index.json with the split); every frame is a scene");
  app.add_option("--temporal", o.temporal, "A temporal model: the radius k of the neighbouring frames it sees (1 or "
                 "2), each warped to the frame along the motion; trains on --shots")
      ->check(CLI::Range(1, 2));
  app.add_option("--val", o.val, "Scenes held out per data folder without an index.json (the last by name)")->capture_default_str();
  app.add_option("--arch", o.arch, "BLOCKS/WIDTH, or BLOCKS,.../WIDTH,... per level (multi-scale)")->capture_default_str();
  app.add_option("--dilations", o.dilations,
                 "Dilation per ResBlock, repeated over the blocks, e.g. 1,2,4,8 (default: none, as in the paper)");
  app.add_flag("--input-skip", o.input_skip,
               "Add the input's log colour to the output: the network learns the correction (a variant)");
  app.add_flag("--autoexposure", o.autoexposure,
               "Variant: scale the colour by the image's autoexposure (the key / its log-average luminance, as OIDN "
               "with key 0.18) before the network and divide its output by it, so that dim and bright renders look "
               "alike to it");
  app.add_option("--exposure-key", o.exposure_key,
                 "With --autoexposure: the log-average luminance the exposure maps an image to (OIDN: 0.18; higher "
                 "puts more of the image where log(1 + c) is logarithmic)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_flag("--demodulate", o.demodulate,
               "Divide the colour by the albedo before the network and multiply its output back (a variant)");
  app.add_option("--prior", o.prior,
                 "Post-correction: refine this model's output (its log colour as 3 more inputs; with --input-skip "
                 "the network learns the correction to it)")
      ->check(CLI::IsMember({"oidn"}));
  app.add_option("--teacher", o.teacher,
                 "Distillation: move each target towards this model's output on the same noisy half (a name -m "
                 "takes or a model file; run once per half by core, post-steps on, x --teacher-ensemble)");
  app.add_option("--teacher-weight", o.teacher_weight,
                 "The teacher's share of each target, in log(1 + c): (1 - w) reference + w teacher")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0))->needs("--teacher");
  app.add_option("--teacher-ensemble", o.teacher_ensemble, "The teacher's self-ensemble: 1, 2, 4 or 8 flips")
      ->capture_default_str()->check(CLI::IsMember({1, 2, 4, 8}))->needs("--teacher");
  app.add_option("--features", o.features, "Feature set")->capture_default_str()->check(CLI::IsMember({"full", "color+albedo+normal", "color", "full+variance"}));
  app.add_option("--steps", o.steps, "Training steps")->capture_default_str();
  app.add_option("--batch", o.batch, "Patches per step")->capture_default_str();
  app.add_option("--patch", o.patch, "Patch edge")->capture_default_str();
  app.add_option("--lr", o.lr, "Peak learning rate")->capture_default_str();
  app.add_option("--val-every", o.val_every, "Validate and checkpoint every K steps")->capture_default_str();
  app.add_option("--checkpoint", o.checkpoint, "Checkpoint folder (default: OUT with .ckpt)");
  app.add_option("--checkpoint-every", o.checkpoint_every, "Also checkpoint every K steps (a killed run loses less)")
      ->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("-o,--out", o.out, "Model file to write (required unless --export-training-set)");
  app.add_option("--name", o.name, "Model name in the metadata");
  app.add_option("--log", o.log, "CSV log of loss and validation (and LOG.scenes.jsonl: each validation per scene)");
  app.add_option("--threads", o.threads, "Threads")->capture_default_str();
  app.add_option("--seed", o.seed, "Random seed")->capture_default_str();
  app.add_flag("-f,--force", o.force, "Replace the output model file");
  std::vector<std::pair<std::string, train::Loss>> loss_names;
  for (const auto& k : train::losses()) loss_names.emplace_back(k.name, k.loss);
  cli::add_enum_option(&app, "--loss", o.loss, loss_names,
                       "l1-log (the paper's), l1-log+mean (adds the L1 of the log patch means), l1-log+ssim (adds "
                 "--ssim-weight x (1 - SSIM) over 3 scales, on the SSIM metric's tonemap) or l1-pu+ssim (the same, "
                 "its L1 on OIDN's PU transfer instead of log(1 + c))");
  app.add_option("--temporal-weight", o.temporal_weight,
                 "Adds this x the L1 of the change of the (log) error between consecutive frames of a shot at each "
                 "pixel: patches come in pairs, frame t and t - 1 (--shots; --batch counts both)")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--relmse-weight", o.relmse_weight,
                 "Adds this weight x relMSE (the metric's, eps 0.01, on linear colour) to the loss")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--lowband-weight", o.lowband_weight,
                 "Adds this weight x the relMSE of the --lowband-width box means (the error's low band: blotches)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--lowband-width", o.lowband_width, "Box edge of --lowband-weight's term, in pixels")
      ->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--edge-ssim-weight", o.edge_ssim_weight,
                 "Adds this weight x the albedo/normal edge pixels' share of 1 - SSIM (full resolution, the metric's "
                 "tonemap): their SSIM loss counted again, on its own")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--ssim-weight", o.ssim_weight, "Weight of the SSIM term of l1-log+ssim and l1-pu+ssim")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  app.add_option("--precise-bn", o.precise_bn,
                 "Before each validation and the export, recompute BN statistics as the plain mean over N batches "
                 "(0: keep the running averages)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  app.add_option("--freeze-bn-after", o.freeze_bn_after,
                 "Fraction of the steps after which BN uses fixed statistics (recomputed there with --precise-bn) "
                 "while training goes on: the last steps train the network as inference runs it (1: never)")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0));
  app.add_option("--init-from", o.init_from,
                 "Start from this model file's weights (same blocks/width; the input planes matched by name, new "
                 "ones zero) instead of He initialisation: fine-tunes a feature-set variant of a trained model")
      ->check(CLI::ExistingFile);
  app.add_option("--grow-from", o.grow_from,
                 "Start from this multi-scale model file with one level added below its bottom, computing exactly "
                 "what the file computes until training teaches the new level (same features, levels and widths "
                 "above it)")
      ->check(CLI::ExistingFile)->excludes("--init-from");
  app.add_option("--widen-from", o.widen_from,
                 "Start from this model file of the same architecture with each level (or the flat network) at "
                 "least as wide here, computing exactly what the file computes until training teaches the new "
                 "channels")
      ->check(CLI::ExistingFile)->excludes("--init-from")->excludes("--grow-from");
  app.add_option("--export-training-set", o.export_set,
                 "Write the training and validation scenes as loaded (feature planes, targets, patch weights) to "
                 "this safetensors file and stop, for tools/models/torch_train.py (a GPU trainer)");
  app.add_option("--quantise", o.quantise,
                 "Quantisation-aware fine-tuning of this model (a name or file) for --precision int8: its weights "
                 "and a range per value trained through the int8 plan's rounding; writes --out and its calibration "
                 "beside it (STEM.int8.json). --steps, --batch, --lr (the weights'), --loss, --teacher apply; the "
                 "architecture is the model's")
      ->excludes("--init-from")->excludes("--grow-from")->excludes("--widen-from");
  app.add_option("--range-lr", o.range_lr, "With --quantise: the learning rate of the ranges (of their logarithms)")
      ->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--range-init", o.range_init,
                 "With --quantise: each range starts at this share of the largest |value| over 16 batches")
      ->capture_default_str()->check(CLI::Range(0.01, 1.0));
  app.add_option("--range-start", o.range_start,
                 "With --quantise: the ranges start as this calibration file gives them (residue-cli calibrate's, "
                 "measured on whole images) instead of --range-init's share of the patches' largest values");
  app.add_option("--quantise-sensitivity", o.quantise_sensitivity,
                 "With --quantise: train nothing; write to this JSON file what rounding each value (alone, and all but "
                 "it) costs the network's output at the starting ranges");
  app.add_flag("--bf16", o.bf16, "Train with CPU autocast to bfloat16 (convolutions), float weights and optimiser: faster on the Zen CPUs measured, slower on an Intel one (MODELS.md, \"Training speed\")");
  CLI11_PARSE(app, argc, argv);
  try {
    return run(o);
  } catch (const Error& e) {
    std::fprintf(stderr, "residue-train: error: %s\n", e.what());
    return e.kind() == ErrorKind::Output ? 4 : e.kind() == ErrorKind::Usage ? 2 : 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "residue-train: %s\n", e.what());
    return 1;
  }
}
