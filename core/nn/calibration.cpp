#include "core/nn/calibration.h"

#include <cmath>
#include <fstream>

#include <nlohmann/json.hpp>

#include "core/io/atomic_file.h"
#include "core/util/error.h"

namespace residue::nn {

namespace {
constexpr const char* kFormat = "residue-int8-calibration-1";
}

std::filesystem::path calibration_path(const std::filesystem::path& model_file) {
  std::filesystem::path p = model_file;
  return p.replace_extension(".int8.json");
}

std::optional<Calibration> read_calibration(const std::filesystem::path& model_file, const Graph& graph) {
  const std::filesystem::path file = calibration_path(model_file);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) return std::nullopt;
  return read_calibration_file(file, graph);
}

Calibration read_calibration_file(const std::filesystem::path& file, const Graph& graph) {
  const std::string where = "int8 calibration '" + file.string() + "'";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) throw Error(ErrorKind::Input, where + ": no such file");
  std::ifstream in(file);
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object()) throw Error(ErrorKind::Input, where + ": not a JSON object");
  if (j.value("format", "") != kFormat)
    throw Error(ErrorKind::Input, where + ": \"format\" must be \"" + kFormat + "\"");
  if (!j.contains("ranges") || !j["ranges"].is_array())
    throw Error(ErrorKind::Input, where + ": no \"ranges\" array");
  if (j["ranges"].size() != static_cast<size_t>(graph.size()) || j.value("graph", "") != graph.summary())
    throw Error(ErrorKind::Input, where + " is for another network (" + j.value("graph", std::string("?")) + ", " +
                                      std::to_string(j["ranges"].size()) + " ranges) than the model (" + graph.summary() +
                                      "): calibrate it again (residue-cli calibrate)");
  Calibration c;
  c.set = j.value("set", "");
  c.statistic = j.value("statistic", c.statistic);
  for (const auto& r : j["ranges"]) {
    if (!r.is_number() || !std::isfinite(r.get<double>()) || r.get<double>() < 0)
      throw Error(ErrorKind::Input, where + ": range " + std::to_string(c.ranges.size()) + " (" + r.dump() +
                                        ") is not a finite value >= 0");
    c.ranges.push_back(r.get<float>());
  }
  return c;
}

void write_calibration(const std::filesystem::path& file, const Graph& graph, const Calibration& c) {
  if (c.ranges.size() != static_cast<size_t>(graph.size()))
    throw Error(ErrorKind::Usage, "a calibration needs one range per op: " + std::to_string(c.ranges.size()) +
                                      " for " + std::to_string(graph.size()) + " ops");
  nlohmann::json j;
  j["format"] = kFormat;
  j["graph"] = graph.summary();
  j["set"] = c.set;
  j["statistic"] = c.statistic;
  j["ranges"] = c.ranges;
  nlohmann::json names = nlohmann::json::array();  // for a reader: which op each range is
  for (const GraphOp& op : graph.ops()) names.push_back(op.name);
  j["ops"] = names;
  io::write_atomically(file, /*overwrite=*/true, [&](const std::filesystem::path& temp) {
    std::ofstream out(temp);
    out << j.dump(1) << "\n";
    if (!out) throw Error(ErrorKind::Output, "cannot write '" + file.string() + "'");
  });
}

void apply_calibration(Graph& graph, const Calibration& c) {
  if (c.ranges.size() != static_cast<size_t>(graph.size()))
    throw Error(ErrorKind::Usage, "a calibration needs one range per op");
  for (int i = 0; i < graph.size(); ++i) graph.set_range(i, c.ranges[static_cast<size_t>(i)]);
}

}  // namespace residue::nn
