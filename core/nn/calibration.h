// int8 calibration (backend.h, Precision::INT8): the largest |value| each op of a model's graph took on a set of
// renders, which the int8 plan quantises that value by (graph_plan_onednn.h). Measured by `residue-cli
// calibrate` (the onednn fp32 backend's record_ranges) and kept beside the model file, NAME.int8.json, so a
// model without one runs fp32 and bf16 only.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/nn/graph.h"

namespace residue::nn {

struct Calibration {
  std::string set;             // what it was measured on, as the model card says it
  std::string statistic = "max |value|";
  std::vector<float> ranges;   // per op of the graph, in its order
};

// multiscale.safetensors -> multiscale.int8.json; rt_hdr_alb_nrm.tza -> rt_hdr_alb_nrm.int8.json
std::filesystem::path calibration_path(const std::filesystem::path& model_file);

// The calibration beside `model_file`, checked against `graph` (its op count and summary); nullopt when there is
// none. Error(Input) naming the file when it does not parse, is for another graph, or holds a range that is not a
// finite value >= 0.
std::optional<Calibration> read_calibration(const std::filesystem::path& model_file, const Graph& graph);
// The calibration file `file` itself, checked as above: Error(Input) when it is missing too.
Calibration read_calibration_file(const std::filesystem::path& file, const Graph& graph);

// Writes `c` for `graph` to `file` (atomically: a complete file or none).
void write_calibration(const std::filesystem::path& file, const Graph& graph, const Calibration& c);

// Sets every op's GraphOp::range from `c` (which must have one range per op).
void apply_calibration(Graph& graph, const Calibration& c);

}  // namespace residue::nn
