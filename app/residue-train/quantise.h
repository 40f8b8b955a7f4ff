// residue-train --quantise MODEL: quantisation-aware fine-tuning of a shipped model for `--precision int8`
// (quantised_graph.h): the model's folded weights and a range per value are trained through the int8 plan's
// rounding, and the result is written as a model file of its own (OUT) with its calibration beside it
// (OUT's stem + .int8.json, core/nn/calibration.h), which core's int8 path reads.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/nn/model_file.h"
#include "training_loss.h"
#include "training_set.h"

namespace residue::train {

struct QuantiseOptions {
  int steps = 2000;
  int batch = 4;
  double lr = 1e-5;        // the weights' peak learning rate (cosine to lr / 100)
  double range_lr = 1e-3;  // the log ranges' (Adam: about this much of log range per step)
  double range_init = 0.25;  // each range starts at this times the largest |value| over the first batches
  std::filesystem::path range_start;  // or: the ranges start as this calibration file gives them (core's, whole images),
  std::vector<float> start_ranges;    // read from it (one per op of the model's graph)
  Loss loss = Loss::L1Log;
  double ssim_weight = 1.0, relmse_weight = 0.0;
  int val_every = 500, checkpoint_every = 250;
  uint32_t seed = 1;
  int threads = 2;
  std::filesystem::path out, checkpoint, log;
  std::filesystem::path sensitivity;  // instead of training: what each value's 8 bits cost, as JSON (quantise.cpp)
  std::string name;   // the new model's name (default: OUT's stem)
  std::string data;   // what it was trained on, for the metadata and the calibration
  bool force = false;
};

// Fine-tunes `model` (a Residue model) on `set`, validating through core's int8 path on `val_scenes` against the
// model's own fp32 result; resumes from the checkpoint folder when it holds a step. With `sensitivity` set it
// trains nothing and writes there what rounding each value costs the network's output. Returns the exit status.
int quantise(const nn::Model& model, const TrainingSet& set, const std::vector<TrainingSource>& val_scenes,
             const QuantiseOptions& o);

}  // namespace residue::train
