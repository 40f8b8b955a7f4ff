#include "core/nn/model_file.h"

#include "core/nn/calibration.h"

#include <cmath>
#include <cstdlib>

#include <nlohmann/json.hpp>

#include "core/nn/model_registry.h"
#include "core/nn/oidn_network.h"
#include "core/nn/tza.h"
#include "core/util/error.h"

namespace residue::nn {
namespace {

constexpr float kBnEps = 1e-5f;

// Takes tensors out of the file, checking each one's shape; what is left at the end was not expected.
class TensorReader {
 public:
  TensorReader(SafetensorsFile& file, std::string where) : file_(file), where_(std::move(where)) {}

  std::vector<float> take(const std::string& name, const std::vector<int64_t>& shape) {
    auto it = file_.tensors.find(name);
    if (it == file_.tensors.end())
      throw Error(ErrorKind::Input, where_ + ": tensor \"" + name + "\" " + shape_to_string(shape) + " is missing");
    if (it->second.shape != shape)
      throw Error(ErrorKind::Input, where_ + ": tensor \"" + name + "\" has shape " + shape_to_string(it->second.shape) +
                                        "; expected " + shape_to_string(shape));
    std::vector<float> v = std::move(it->second.values);
    file_.tensors.erase(it);
    check_finite(v, where_, name);
    return v;
  }

  Conv3x3 conv(const std::string& prefix, int in, int out, bool bias) {
    Conv3x3 c;
    c.in = in;
    c.out = out;
    c.weight = take(prefix + ".weight", {out, in, 3, 3});
    c.bias = bias ? take(prefix + ".bias", {out}) : std::vector<float>(static_cast<size_t>(out), 0.0f);
    return c;
  }

  BatchNorm bn(const std::string& prefix, int n, float eps) {
    BatchNorm b;
    b.gamma = take(prefix + ".weight", {n});
    b.beta = take(prefix + ".bias", {n});
    b.mean = take(prefix + ".running_mean", {n});
    b.var = take(prefix + ".running_var", {n});
    b.eps = eps;
    return b;
  }

  void expect_empty() const {
    if (!file_.tensors.empty())
      throw Error(ErrorKind::Input, where_ + ": unexpected tensor \"" + file_.tensors.begin()->first +
                                        "\" (not part of the architecture its metadata describes)");
  }

 private:
  SafetensorsFile& file_;
  std::string where_;
};

// Batch norm's epsilon: a finite number in [0, 1] ("abc" or "1e999" are refused, naming the key).
float metadata_eps(const std::string& text, const std::string& where) {
  try {
    size_t used = 0;
    const double v = std::stod(text, &used);
    if (used == text.size() && std::isfinite(v) && v >= 0 && v <= 1) return static_cast<float>(v);
  } catch (const std::exception&) {
  }
  throw Error(ErrorKind::Input, where + ": metadata \"residue.bn_eps\" = \"" + text + "\" is not a number in [0, 1]");
}

int metadata_int(const std::map<std::string, std::string>& m, const std::string& key, const std::string& where) {
  auto it = m.find(key);
  if (it == m.end()) throw Error(ErrorKind::Input, where + ": metadata \"" + key + "\" is missing");
  try {
    size_t used = 0;
    const int v = std::stoi(it->second, &used);
    if (used == it->second.size() && v > 0) return v;
  } catch (const std::exception&) {
  }
  throw Error(ErrorKind::Input, where + ": metadata \"" + key + "\" = \"" + it->second + "\" is not a positive integer");
}

// OIDN's networks are named rt_<hdr|ldr>[_alb|_calb][_nrm|_cnrm][_small|_large], or rt_alb / rt_nrm
// [_large] for the auxiliary prefilters.
OidnInputs oidn_inputs(const std::string& stem, const std::string& where) {
  OidnInputs in;
  auto has = [&](const std::string& part) { return ("_" + stem + "_").find("_" + part + "_") != std::string::npos; };
  if (stem.rfind("rt_", 0) != 0) throw Error(ErrorKind::Input, where + ": not an OIDN RT network name (rt_...)");
  if (has("hdr")) in.hdr = true;
  else if (has("ldr")) in.hdr = false;
  else if (has("alb") || has("nrm")) {  // a prefilter: that image alone
    in.color = false;
    in.hdr = false;
    in.albedo = has("alb");
    in.normal = has("nrm");
    return in;
  } else {
    throw Error(ErrorKind::Input, where + ": cannot tell from the name which inputs this OIDN network takes");
  }
  in.albedo = has("alb") || has("calb");
  in.normal = has("nrm") || has("cnrm");
  in.clean_aux = has("calb") || has("cnrm");
  return in;
}

Model load_oidn_model(const std::filesystem::path& path) {
  const std::string where = "OIDN network '" + path.string() + "'";
  Model m;
  m.path = path.string();
  m.name = path.stem().string();
  m.method = Method::Oidn;
  m.oidn = oidn_inputs(m.name, where);
  const int channels = 3 * (int{m.oidn.color} + int{m.oidn.albedo} + int{m.oidn.normal});
  m.graph = oidn_graph(read_tza(path), channels, where);
  if (m.oidn.clean_aux) {
    const auto dir = path.parent_path();
    const std::string size = m.name.size() > 6 && m.name.substr(m.name.size() - 6) == "_large" ? "_large" : "";
    for (const char* aux : {"alb", "nrm"}) {
      const auto file = dir / (std::string("rt_") + aux + size + ".tza");
      if (!std::filesystem::is_regular_file(file))
        throw Error(ErrorKind::Input, where + " denoises with clean albedo and normal; its prefilter " + file.string() +
                                          " is missing");
      (aux[0] == 'a' ? m.albedo_prefilter : m.normal_prefilter) = std::make_shared<const Model>(load_oidn_model(file));
    }
  }
  return m;
}

Model load_residue_model(const std::filesystem::path& path);

}  // namespace

FeatureSet Model::features() const {
  if (method == Method::Residue) return network.arch.features;
  return oidn.albedo && oidn.normal ? FeatureSet::ColorAlbedoNormal : FeatureSet::ColorOnly;
}

std::string Model::architecture() const {
  if (method == Method::Residue) return network.arch.to_string();
  return std::string("OIDN ") + oidn_network_name(graph) + " (" + name + ")";
}

Model model_from_network(Network network, std::string name) {
  Model m;
  m.name = std::move(name);
  m.graph = to_graph(network);
  m.network = std::move(network);
  return m;
}

Model load_model(const std::filesystem::path& path) {
  Model m = path.extension() == ".tza" ? load_oidn_model(path) : load_residue_model(path);
  if (const auto c = read_calibration(path, m.graph)) {
    apply_calibration(m.graph, *c);
    m.int8_calibration = c->statistic + " over " + c->set;
  }
  return m;
}

namespace {

Model load_residue_model(const std::filesystem::path& path) {
  const std::string where = "model file '" + path.string() + "'";
  SafetensorsFile file = read_safetensors(path);
  const auto& md = file.metadata;
  if (md.count("residue.format") == 0 || md.at("residue.format") != "1")
    throw Error(ErrorKind::Input, where + ": not a Residue model (metadata residue.format = \"1\" expected)");
  Architecture arch;
  arch.blocks = metadata_int(md, "residue.blocks", where);
  arch.width = metadata_int(md, "residue.width", where);
  const auto features = md.count("residue.features") ? feature_set_from_string(md.at("residue.features")) : std::nullopt;
  if (!features)
    throw Error(ErrorKind::Input, where + ": metadata \"residue.features\" must be full, color+albedo+normal or color");
  arch.features = *features;
  if (md.count("residue.dilations")) {
    const auto d = parse_dilations(md.at("residue.dilations"));
    if (!d)
      throw Error(ErrorKind::Input, where + ": metadata \"residue.dilations\" = \"" + md.at("residue.dilations") +
                                        "\" is not a list of dilations from 1 to 64 (\"1,2,4,8\")");
    arch.dilations = *d;
  }
  if (md.count("residue.levels") || md.count("residue.widths")) {
    const auto levels = md.count("residue.levels") ? parse_ints(md.at("residue.levels"), 1, 64) : std::nullopt;
    const auto widths = md.count("residue.widths") ? parse_ints(md.at("residue.widths"), 1, 4096) : std::nullopt;
    if (!levels || !widths || levels->size() != widths->size() || levels->size() < 2 || levels->size() > 6)
      throw Error(ErrorKind::Input, where + ": metadata \"residue.levels\" and \"residue.widths\" must list, for 2 to 6 "
                                    "levels, the ResBlocks (1-64) and the width (1-4096) of each (\"2,2,4\" and \"32,48,64\")");
    arch.levels = *levels;
    arch.widths = *widths;
    arch.blocks = arch.levels.front();
    arch.width = arch.widths.front();
  }
  // A variant's switch: absent (off), "0" or "1".
  auto flag = [&](const std::string& key) {
    const auto it = md.find(key);
    if (it == md.end()) return false;
    if (it->second != "0" && it->second != "1")
      throw Error(ErrorKind::Input, where + ": metadata \"" + key + "\" must be 0 or 1, not \"" + it->second + "\"");
    return it->second == "1";
  };
  arch.input_skip = flag("residue.input_skip");
  arch.autoexposure = flag("residue.autoexposure");
  if (const auto it = md.find("residue.exposure_key"); it != md.end()) {
    char* end = nullptr;
    const float key = std::strtof(it->second.c_str(), &end);
    if (end == it->second.c_str() || *end != '\0' || !(key > 0.0f) || !std::isfinite(key))
      throw Error(ErrorKind::Input, where + ": metadata \"residue.exposure_key\" must be a positive number, not \"" +
                                        it->second + "\"");
    arch.exposure_key = key;
  }
  arch.demodulate = flag("residue.demodulate");
  if (md.count("residue.prior")) {
    arch.prior = md.at("residue.prior");
    if (arch.prior != "oidn")
      throw Error(ErrorKind::Input, where + ": metadata \"residue.prior\" must be \"oidn\" (a full-AOV model refining Open "
                                    "Image Denoise's rt_hdr_alb_nrm), not \"" + arch.prior + "\"");
  }
  if (const auto it = md.find("residue.temporal"); it != md.end()) {
    const auto k = parse_ints(it->second, 1, 2);
    if (!k || k->size() != 1)
      throw Error(ErrorKind::Input, where + ": metadata \"residue.temporal\" must be the radius of the frames it sees, 1 "
                                    "or 2, not \"" + it->second + "\"");
    arch.temporal = k->front();
  }
  if (const auto c = arch.contradiction()) throw Error(ErrorKind::Input, where + ": " + *c);
  const float eps = md.count("residue.bn_eps") ? metadata_eps(md.at("residue.bn_eps"), where) : kBnEps;

  Model m;
  m.path = path.string();
  m.metadata = md;
  m.name = md.count("name") ? md.at("name") : path.stem().string();
  if (const auto it = md.find("residue.ensemble"); it != md.end()) {
    if (it->second != "1" && it->second != "2" && it->second != "4" && it->second != "8")
      throw Error(ErrorKind::Input, where + ": metadata \"residue.ensemble\" must be 1, 2, 4 or 8 (the flips and "
                                    "transposes averaged), not \"" + it->second + "\"");
    m.ensemble = std::stoi(it->second);
  }
  Network& n = m.network;
  n.arch = arch;
  const int w = arch.level_width(0);
  TensorReader r(file, where);
  n.head = r.conv("head.conv", arch.in_channels(), w, true);
  n.head_prelu = r.take("head.prelu.weight", {w});
  auto block = [&](const std::string& p, int width) {
    ResBlock blk;
    blk.conv1 = fold_batch_norm(r.conv(p + ".conv1", width, width, false), r.bn(p + ".bn1", width, eps));
    blk.prelu = r.take(p + ".prelu.weight", {width});
    blk.conv2 = fold_batch_norm(r.conv(p + ".conv2", width, width, false), r.bn(p + ".bn2", width, eps));
    return blk;
  };
  // conv (no bias) -> BN -> PReLU: the multi-scale network's down and up steps.
  auto conv_prelu = [&](const std::string& p, int in, int out) {
    return ConvPRelu{fold_batch_norm(r.conv(p + ".conv", in, out, false), r.bn(p + ".bn", out, eps)),
                     r.take(p + ".prelu.weight", {out})};
  };
  if (!arch.multiscale()) {
    for (int b = 0; b < arch.blocks; ++b) n.blocks.push_back(block("blocks." + std::to_string(b), w));
  } else {
    const int L = static_cast<int>(arch.levels.size());
    n.scales.resize(static_cast<size_t>(L));
    for (int l = 0; l < L; ++l) {
      const std::string p = "levels." + std::to_string(l);
      const int lw = arch.level_width(l);
      ScaleLevel& s = n.scales[static_cast<size_t>(l)];
      for (int b = 0; b < arch.levels[static_cast<size_t>(l)]; ++b) s.enc.push_back(block(p + ".enc." + std::to_string(b), lw));
      if (l + 1 == L) break;
      s.down = conv_prelu(p + ".down", lw, arch.level_width(l + 1));
      s.up = conv_prelu(p + ".up", arch.level_width(l + 1) + lw, lw);
      for (int b = 0; b < arch.levels[static_cast<size_t>(l)]; ++b) s.dec.push_back(block(p + ".dec." + std::to_string(b), lw));
    }
  }
  n.tail = fold_batch_norm(r.conv("tail.conv", w, w, false), r.bn("tail.bn", w, eps));
  n.out = r.conv("out.conv", w, 3, true);
  r.expect_empty();
  m.graph = to_graph(n);
  if (!arch.prior.empty()) {
    try {
      m.prior = std::make_shared<const Model>(load_model(find_model_for(arch.prior, FeatureSet::Full)));
    } catch (const Error& e) {
      throw Error(ErrorKind::Input, where + " refines the output of \"" + arch.prior + "\", which cannot be loaded: " + e.what());
    }
  }
  return m;
}

}  // namespace

void write_architecture_metadata(const Architecture& arch, std::map<std::string, std::string>& metadata) {
  metadata["residue.format"] = "1";
  metadata["residue.blocks"] = std::to_string(arch.blocks);
  metadata["residue.width"] = std::to_string(arch.width);
  metadata["residue.features"] = to_string(arch.features);
  if (arch.max_dilation() > 1) metadata["residue.dilations"] = dilations_to_string(arch.dilations);
  if (arch.input_skip) metadata["residue.input_skip"] = "1";
  if (arch.demodulate) metadata["residue.demodulate"] = "1";
  if (arch.autoexposure) {
    metadata["residue.autoexposure"] = "1";
    metadata["residue.exposure_key"] = exposure_key_string(arch.exposure_key);
  }
  if (!arch.prior.empty()) metadata["residue.prior"] = arch.prior;
  if (arch.temporal > 0) metadata["residue.temporal"] = std::to_string(arch.temporal);
  if (arch.multiscale()) {
    metadata["residue.levels"] = ints_to_string(arch.levels);
    metadata["residue.widths"] = ints_to_string(arch.widths);
  }
}

SafetensorsFile to_safetensors(const Network& n, std::map<std::string, std::string> metadata) {
  SafetensorsFile f;
  f.metadata = std::move(metadata);
  write_architecture_metadata(n.arch, f.metadata);
  f.metadata["residue.bn_eps"] = "0";
  auto put = [&](const std::string& name, std::vector<int64_t> shape, const std::vector<float>& v) {
    f.tensors[name] = Tensor{"F32", std::move(shape), v};
  };
  auto conv = [&](const std::string& p, const Conv3x3& c, bool bias) {
    put(p + ".weight", {c.out, c.in, 3, 3}, c.weight);
    if (bias) put(p + ".bias", {c.out}, c.bias);
  };
  // The weights are folded already: batch norm becomes identity with the conv's bias as its beta (eps 0).
  auto bn = [&](const std::string& p, const Conv3x3& c) {
    const int64_t w = c.out;
    put(p + ".weight", {w}, std::vector<float>(static_cast<size_t>(w), 1.0f));
    put(p + ".bias", {w}, c.bias);
    put(p + ".running_mean", {w}, std::vector<float>(static_cast<size_t>(w), 0.0f));
    put(p + ".running_var", {w}, std::vector<float>(static_cast<size_t>(w), 1.0f));
  };
  auto block = [&](const std::string& p, const ResBlock& b) {
    conv(p + ".conv1", b.conv1, false);
    bn(p + ".bn1", b.conv1);
    put(p + ".prelu.weight", {b.conv1.out}, b.prelu);
    conv(p + ".conv2", b.conv2, false);
    bn(p + ".bn2", b.conv2);
  };
  auto conv_prelu = [&](const std::string& p, const ConvPRelu& c) {
    conv(p + ".conv", c.conv, false);
    bn(p + ".bn", c.conv);
    put(p + ".prelu.weight", {c.conv.out}, c.prelu);
  };
  conv("head.conv", n.head, true);
  put("head.prelu.weight", {n.head.out}, n.head_prelu);
  for (size_t b = 0; b < n.blocks.size(); ++b) block("blocks." + std::to_string(b), n.blocks[b]);
  for (size_t l = 0; l < n.scales.size(); ++l) {
    const std::string p = "levels." + std::to_string(l);
    const ScaleLevel& s = n.scales[l];
    for (size_t b = 0; b < s.enc.size(); ++b) block(p + ".enc." + std::to_string(b), s.enc[b]);
    if (l + 1 == n.scales.size()) break;
    conv_prelu(p + ".down", s.down);
    conv_prelu(p + ".up", s.up);
    for (size_t b = 0; b < s.dec.size(); ++b) block(p + ".dec." + std::to_string(b), s.dec[b]);
  }
  conv("tail.conv", n.tail, false);
  bn("tail.bn", n.tail);
  conv("out.conv", n.out, true);
  return f;
}

}  // namespace residue::nn
