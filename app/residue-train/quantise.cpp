#include "quantise.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>

#include <nlohmann/json.hpp>

#include "core/denoise/denoiser.h"
#include "core/metrics/metrics.h"
#include "core/nn/calibration.h"
#include "core/nn/safetensors.h"
#include "core/util/error.h"
#include "checkpoint.h"
#include "quantised_graph.h"

namespace fs = std::filesystem;

namespace residue::train {

namespace {

// The model with `q`'s weights and ranges, as a model file and its calibration beside it (core reads both).
void write_quantised(const nn::Model& model, const QuantisedGraph& q, const fs::path& file,
                     std::map<std::string, std::string> metadata, const std::string& calibrated_on, bool force) {
  nn::Graph graph = model.graph;
  q->write_to(graph);
  nn::Network network = model.network;
  nn::set_weights_from_graph(network, graph);
  nn::write_safetensors(file, nn::to_safetensors(network, std::move(metadata)), force);
  nn::Calibration c;
  c.set = calibrated_on;
  c.statistic = "learnt by quantisation-aware training";
  c.ranges = q->ranges();
  nn::write_calibration(nn::calibration_path(file), graph, c);
}

struct Scores {
  double relmse = 0, ssim = 0;
  nlohmann::json per_scene = nlohmann::json::array();
};

// Every scene denoised by core as `-m FILE --precision P` runs it, and scored against its reference.
Scores score(const nn::Model& model, const std::vector<TrainingSource>& scenes, nn::Precision precision) {
  Scores s;
  DenoiseOptions d;
  d.skip_empty_tiles = false;
  d.precision = precision;
  d.backend = "onednn";
  for (const TrainingSource& source : scenes) {
    const AovStack stack = load_source(source, 0);
    const auto m = metrics::compare(denoise(stack, model, d), stack.reference->image);
    s.relmse += m.relmse / static_cast<double>(scenes.size());
    s.ssim += m.ssim / static_cast<double>(scenes.size());
    s.per_scene.push_back({{"scene", source.name()}, {"relmse", m.relmse}, {"ssim", m.ssim}});
  }
  return s;
}

// What each value's 8 bits cost, at the starting ranges: the network's output (log colour) with only that value
// (and its conv's weights) rounded, and with every value rounded but it, against the float network's; RMS over
// 8 batches of the trainer's patches. The second says what keeping the value in f32 would save.
int sensitivity(const nn::Graph& graph, QuantisedGraph& q, const TrainingSet& set, const QuantiseOptions& o, std::mt19937& rng) {
  torch::NoGradGuard no_grad;
  std::vector<torch::Tensor> xs, floats;
  for (int b = 0; b < 8; ++b) {
    torch::Tensor x, y;
    set.sample(rng, o.batch, x, y);
    xs.push_back(x);
    floats.push_back(q->forward(x, false));
  }
  const auto rms = [&](const std::vector<bool>& rounded) {
    double sum = 0, n = 0;
    for (size_t b = 0; b < xs.size(); ++b) {
      const torch::Tensor d = q->forward(xs[b], rounded) - floats[b];
      sum += d.pow(2).sum().item<double>();
      n += static_cast<double>(d.numel());
    }
    return std::sqrt(sum / n);
  };
  const std::vector<bool> all(static_cast<size_t>(q->size()), true);
  const double every = rms(all);
  const std::vector<float> ranges = q->ranges();
  nlohmann::json rows = nlohmann::json::array();
  for (int i = 0; i < q->size(); ++i) {
    if (!q->rounds(i)) continue;
    std::vector<bool> alone(all.size(), false), but(all);
    alone[static_cast<size_t>(i)] = true;
    but[static_cast<size_t>(i)] = false;
    const nn::GraphOp& op = graph.op(i);
    rows.push_back({{"op", i}, {"name", op.name}, {"channels", op.channels}, {"level", op.level},
                    {"range", ranges[static_cast<size_t>(i)]}, {"alone", rms(alone)}, {"all_but", rms(but)}});
    std::printf("%3d %-24s level %d  %3d ch  alone %.5f  every value but it %.5f (every value %.5f)\n", i, op.name.c_str(),
                op.level, op.channels, rows.back()["alone"].get<double>(), rows.back()["all_but"].get<double>(), every);
    std::fflush(stdout);
  }
  const nlohmann::json j{{"what", "RMS of the network's output (log colour) against the float network's, 8 batches of " +
                                      std::to_string(o.batch) + " patches: each value alone rounded, and every value but it"},
                         {"ranges_from", o.range_start.empty() ? "--range-init " + std::to_string(o.range_init) : o.range_start.string()},
                         {"every_value", every}, {"values", rows}};
  std::ofstream(o.sensitivity) << j.dump(1) << "\n";
  std::printf("wrote %s\n", o.sensitivity.string().c_str());
  return 0;
}

}  // namespace

int quantise(const nn::Model& model, const TrainingSet& set, const std::vector<TrainingSource>& val_scenes,
             const QuantiseOptions& o) {
  if (model.method != nn::Method::Residue)
    throw Error(ErrorKind::Usage, "--quantise: " + model.name + " is not a Residue model");
  if (o.sensitivity.empty() && fs::exists(o.out) && !o.force) throw Error(ErrorKind::Output, "output '" + o.out.string() + "' exists; pass --force");
  torch::manual_seed(o.seed);
  std::mt19937 rng(o.seed);
  const fs::path ckpt = o.checkpoint.empty() ? fs::path(o.out).replace_extension(".ckpt") : o.checkpoint;
  const bool resuming = fs::exists(ckpt / "step");

  // Starting ranges: a share of the largest |value| each op takes over a few batches (the float network's).
  std::vector<float> largest(static_cast<size_t>(model.graph.size()), 0.0f);
  {
    QuantisedGraph probe(model.graph, std::vector<float>(largest.size(), 1.0f));
    torch::NoGradGuard no_grad;
    for (int b = 0; b < 16; ++b) {
      torch::Tensor x, y;
      set.sample(rng, o.batch, x, y);
      probe->forward(x, false, &largest);
    }
  }
  std::vector<float> start(largest.size());
  for (size_t i = 0; i < largest.size(); ++i) start[i] = largest[i] > 0 ? largest[i] * static_cast<float>(o.range_init) : 1.0f;
  if (!o.start_ranges.empty())
    for (size_t i = 0; i < start.size(); ++i) start[i] = o.start_ranges[i] > 0 ? o.start_ranges[i] : start[i];
  QuantisedGraph q(model.graph, start);
  if (!o.sensitivity.empty()) return sensitivity(model.graph, q, set, o, rng);
  fs::create_directories(ckpt);

  torch::optim::Adam opt({torch::optim::OptimizerParamGroup(q->weight_parameters(), std::make_unique<torch::optim::AdamOptions>(o.lr)),
                          torch::optim::OptimizerParamGroup(q->range_parameters(), std::make_unique<torch::optim::AdamOptions>(o.range_lr))},
                         torch::optim::AdamOptions(o.lr));
  int step = 0;
  if (resuming) step = load_checkpoint(ckpt, q, opt);
  if (resuming) std::printf("resumed from %s at step %d\n", ckpt.string().c_str(), step);
  rng.seed(o.seed + static_cast<uint32_t>(step));

  const std::string calibrated_on = o.data + " (" + std::to_string(set.size()) + " training scenes, patches of the "
                                    "trainer's sampling)";
  const fs::path tmp_model = ckpt / "validation.safetensors";
  std::map<std::string, std::string> metadata = model.metadata;
  metadata["name"] = o.name.empty() ? o.out.stem().string() : o.name;
  metadata["quantised_from"] = model.name;
  for (const char* stale : {"benchmark", "validation", "averaged_from"}) metadata.erase(stale);

  std::printf("fp32 of %s on the %zu validation scenes...\n", model.name.c_str(), val_scenes.size());
  std::fflush(stdout);
  const Scores fp32 = score(model, val_scenes, nn::Precision::FP32);
  std::printf("fp32 relMSE %.6f SSIM %.5f\n", fp32.relmse, fp32.ssim);
  std::ofstream log;
  if (!o.log.empty()) {
    log.open(o.log, step == 0 ? std::ios::trunc : std::ios::app);
    if (step == 0) log << "step,loss,lr,seconds_per_step,int8_relmse,int8_ssim,fp32_relmse,fp32_ssim\n";
  }
  Scores last;
  auto validate = [&] {
    if (fs::exists(tmp_model)) fs::remove(tmp_model);
    write_quantised(model, q, tmp_model, metadata, calibrated_on, true);
    last = score(nn::load_model(tmp_model), val_scenes, nn::Precision::INT8);
  };
  double loss_sum = 0;
  int loss_n = 0;
  auto t_last = std::chrono::steady_clock::now();
  while (step < o.steps) {
    const double lr = cosine_learning_rate(o.lr, step, o.steps);
    auto& groups = opt.param_groups();
    static_cast<torch::optim::AdamOptions&>(groups[0].options()).lr(lr);
    static_cast<torch::optim::AdamOptions&>(groups[1].options()).lr(cosine_learning_rate(o.range_lr, step, o.steps));
    torch::Tensor x, y;
    set.sample(rng, o.batch, x, y);
    opt.zero_grad();
    const torch::Tensor prediction = q->forward(x);
    torch::Tensor loss = training_loss(o.loss, prediction, y, o.ssim_weight);
    if (o.relmse_weight > 0) loss = loss + o.relmse_weight * relative_mse(prediction, y);
    loss.backward();
    torch::nn::utils::clip_grad_norm_(q->weight_parameters(), 1.0);
    opt.step();
    loss_sum += loss.item<double>();
    ++loss_n;
    ++step;
    const bool do_val = !val_scenes.empty() && (step % o.val_every == 0 || step == o.steps);
    if (step % 50 == 0 || do_val) {
      const double sps = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_last).count() / loss_n;
      if (do_val) validate();
      if (do_val || step % o.checkpoint_every == 0) save_checkpoint(ckpt, q, opt, step);
      std::printf("step %6d  loss %.5f  lr %.2e  %.3f s/step", step, loss_sum / loss_n, lr, sps);
      if (do_val) std::printf("  int8 relMSE %.6f (fp32 %.6f, %+.2f %%) SSIM %.5f (fp32 %.5f)", last.relmse, fp32.relmse,
                              100.0 * (last.relmse / fp32.relmse - 1.0), last.ssim, fp32.ssim);
      std::printf("\n");
      std::fflush(stdout);
      if (log.is_open())
        log << step << "," << loss_sum / loss_n << "," << lr << "," << sps << ","
            << (do_val ? std::to_string(last.relmse) + "," + std::to_string(last.ssim) : ",") << "," << fp32.relmse
            << "," << fp32.ssim << "\n" << std::flush;
      loss_sum = 0;
      loss_n = 0;
      t_last = std::chrono::steady_clock::now();
    }
  }
  if (!val_scenes.empty() && last.per_scene.empty()) validate();
  metadata["training"] = nlohmann::json{
      {"quantisation_aware", true}, {"from", model.name}, {"data", o.data}, {"train_scenes", set.size()},
      {"steps", o.steps}, {"batch", o.batch}, {"lr", o.lr}, {"range_lr", o.range_lr}, {"range_init", o.range_init}, {"range_start", o.range_start.string()},
      {"loss", std::string(loss_kind(o.loss).description) + (o.relmse_weight > 0 ? " + w * relMSE (eps 0.01)" : "")},
      {"relmse_weight", o.relmse_weight}, {"seed", o.seed}, {"threads", o.threads},
      {"schedule", "cosine to lr/100, 100 warm-up"}, {"optimizer", "Adam(0.9, 0.999), weights' grad clip 1.0"}}
                             .dump();
  metadata["validation"] = nlohmann::json{{"scenes", val_scenes.size()}, {"precision", "int8"},
                                          {"relmse", last.relmse}, {"ssim", last.ssim},
                                          {"fp32_relmse", fp32.relmse}, {"fp32_ssim", fp32.ssim},
                                          {"per_scene", last.per_scene}, {"fp32_per_scene", fp32.per_scene}}
                               .dump();
  write_quantised(model, q, o.out, metadata, calibrated_on, o.force);
  std::printf("wrote %s and %s\n", o.out.string().c_str(), nn::calibration_path(o.out).string().c_str());
  return 0;
}

}  // namespace residue::train
