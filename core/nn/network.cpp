#include "core/nn/network.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <random>

namespace residue::nn {

double Architecture::flops_per_pixel() const {
  const double k = 9.0 * 2.0;  // 3x3 taps, multiply + add
  if (!multiscale()) return k * (in_channels() * width + (2.0 * blocks + 1.0) * width * width + width * 3.0);
  const int L = static_cast<int>(levels.size());
  double f = in_channels() * level_width(0) + level_width(0) * level_width(0) + level_width(0) * 3.0;  // head, tail, out
  for (int l = 0; l < L; ++l) {
    const double w = level_width(l), area = 1.0 / static_cast<double>(1 << (2 * l));
    const int blocks_here = l + 1 < L ? 2 * levels[static_cast<size_t>(l)] : levels[static_cast<size_t>(l)];
    double level = 2.0 * blocks_here * w * w;
    if (l + 1 < L) level += (level_width(l + 1) + w) * w;  // up (at level l)
    if (l > 0) level += level_width(l - 1) * w;            // down into level l
    f += level * area;
  }
  return k * f;
}

int Architecture::conv_layers() const {
  if (!multiscale()) return 2 * blocks + 3;
  int n = 3;
  const int L = static_cast<int>(levels.size());
  for (int l = 0; l < L; ++l) n += (l + 1 < L ? 4 : 2) * levels[static_cast<size_t>(l)] + (l + 1 < L ? 2 : 0);
  return n;
}

int Architecture::max_dilation() const {
  int d = 1;
  for (int b = 0; b < blocks; ++b) d = std::max(d, dilation(b));
  return d;
}

int Architecture::halo() const {
  int h = 3;  // head, tail, out
  if (!multiscale()) {
    for (int b = 0; b < blocks; ++b) h += 2 * dilation(b);
    return h;
  }
  // Along the deepest path (graph.h's reach): each conv at level l reaches 2^l px, each upsample into level l
  // adds 2^l, ResBlocks run at each level on the way down and (above the bottom) up.
  const int L = static_cast<int>(levels.size());
  for (int l = 0; l < L; ++l) {
    const int px = 1 << l;
    h += (l + 1 < L ? 4 : 2) * levels[static_cast<size_t>(l)] * px;
    if (l > 0) h += px;           // the down conv into level l
    if (l + 1 < L) h += px + px;  // the upsample into level l and the up conv
  }
  const int a = alignment();
  return (h + a - 1) / a * a;
}

std::string dilations_to_string(const std::vector<int>& d) {
  std::string s;
  for (size_t i = 0; i < d.size(); ++i) s += (i ? "," : "") + std::to_string(d[i]);
  return s;
}

std::optional<std::vector<int>> parse_dilations(const std::string& text) { return parse_ints(text, 1, 64); }

std::string ints_to_string(const std::vector<int>& v) { return dilations_to_string(v); }

std::optional<std::vector<int>> parse_ints(const std::string& text, int lo, int hi) {
  std::vector<int> d;
  size_t pos = 0;
  while (pos <= text.size()) {
    const size_t comma = std::min(text.find(',', pos), text.size());
    const std::string item = text.substr(pos, comma - pos);
    if (item.empty() || item.size() > 5 || item.find_first_not_of("0123456789") != std::string::npos) return std::nullopt;
    const int v = std::stoi(item);
    if (v < lo || v > hi) return std::nullopt;
    d.push_back(v);
    pos = comma + 1;
  }
  return d;
}

std::string exposure_key_string(float key) {
  char text[32];
  for (int digits = 1;; ++digits) {  // the shortest that reads back the same float (9 digits always do)
    std::snprintf(text, sizeof text, "%.*g", digits, static_cast<double>(key));
    if (digits == 9 || std::strtof(text, nullptr) == key) return text;
  }
}

std::optional<std::string> Architecture::contradiction() const {
  if (multiscale() && (levels.size() != widths.size() || levels.size() < 2 || levels.size() > 6))
    return "a multi-scale network has 2 to 6 levels, each with its number of ResBlocks and its width";
  if (multiscale() && !dilations.empty()) return "a multi-scale network has no dilations";
  if (demodulate && features == FeatureSet::ColorOnly)
    return "demodulation needs the albedo, which the \"color\" feature set does not have";
  if (!prior.empty() && features != FeatureSet::Full)
    return "a post-correction model (a prior) reads the \"full\" feature set, not \"" + std::string(residue::to_string(features)) + "\"";
  if (temporal < 0 || temporal > 2) return "a temporal model sees 1 or 2 frames each side, not " + std::to_string(temporal);
  if (temporal > 0 && (features != FeatureSet::Full || demodulate || !prior.empty()))
    return "a temporal model reads the \"full\" feature set, not demodulated and with no prior";
  return std::nullopt;
}

std::string Architecture::autoexposure_string() const {
  if (!autoexposure) return "";
  return exposure_key == kOidnExposureKey ? " autoexposure" : " autoexposure " + exposure_key_string(exposure_key);
}

std::vector<std::string> input_planes(const Architecture& arch) {
  std::vector<std::string> planes = feature_planes(arch.features);
  if (!arch.prior.empty())
    for (const char* c : {"prior.r", "prior.g", "prior.b"}) planes.push_back(c);
  for (int d : neighbour_offsets(arch.temporal)) {
    const std::string frame = (d < 0 ? "t" : "t+") + std::to_string(d) + ".";
    for (const char* c : {"color.r", "color.g", "color.b", "valid"}) planes.push_back(frame + c);
  }
  return planes;
}

std::string Architecture::to_string() const {
  if (multiscale())
    return "ms " + ints_to_string(levels) + "/" + ints_to_string(widths) + " " + residue::to_string(features) +
           (input_skip ? " input-skip" : "") + (demodulate ? " demodulated" : "") + autoexposure_string() + (prior.empty() ? "" : " refines " + prior) +
           (temporal > 0 ? " temporal " + std::to_string(temporal) : "");
  std::string s = std::to_string(blocks) + "/" + std::to_string(width) + " " + residue::to_string(features);
  if (max_dilation() > 1) s += " dilated " + dilations_to_string(dilations);
  if (input_skip) s += " input-skip";
  if (demodulate) s += " demodulated";
  s += autoexposure_string();
  if (!prior.empty()) s += " refines " + prior;
  if (temporal > 0) s += " temporal " + std::to_string(temporal);
  return s;
}

Conv3x3 fold_batch_norm(const Conv3x3& conv, const BatchNorm& bn) {
  Conv3x3 f = conv;
  if (f.bias.empty()) f.bias.assign(static_cast<size_t>(f.out), 0.0f);
  for (int o = 0; o < f.out; ++o) {
    const size_t oi = static_cast<size_t>(o);
    const double scale = bn.gamma[oi] / std::sqrt(static_cast<double>(bn.var[oi]) + bn.eps);
    for (int k = 0; k < f.in * 9; ++k) {
      float& w = f.weight[static_cast<size_t>(o * f.in * 9 + k)];
      w = static_cast<float>(w * scale);
    }
    f.bias[oi] = static_cast<float>((f.bias[oi] - bn.mean[oi]) * scale + bn.beta[oi]);
  }
  return f;
}

Graph to_graph(const Network& n) {
  Graph g;
  auto conv = [&](const std::string& name, int x, const Conv3x3& c, const std::vector<float>& prelu, int dilation,
                  int residual) {
    return g.conv(name, {x}, c.out, 3, c.weight, c.bias, prelu.empty() ? Activation::None : Activation::PReLU, prelu,
                  dilation, residual);
  };
  auto blocks = [&](const std::string& prefix, int y, const std::vector<ResBlock>& bs, bool dilate) {
    for (size_t b = 0; b < bs.size(); ++b) {
      const std::string p = prefix + std::to_string(b);
      const int d = dilate ? n.arch.dilation(static_cast<int>(b)) : 1;
      const int t = conv(p + ".conv1", y, bs[b].conv1, bs[b].prelu, d, -1);
      y = conv(p + ".conv2", t, bs[b].conv2, {}, d, y);
    }
    return y;
  };
  const int input = g.input(n.arch.in_channels());
  const int head = conv("head", input, n.head, n.head_prelu, 1, -1);
  int y = head;
  if (!n.arch.multiscale()) {
    y = blocks("blocks.", y, n.blocks, true);
  } else {
    const int L = static_cast<int>(n.scales.size());
    std::vector<int> skips;
    for (int l = 0; l < L; ++l) {
      const ScaleLevel& s = n.scales[static_cast<size_t>(l)];
      const std::string p = "levels." + std::to_string(l);
      y = blocks(p + ".enc.", y, s.enc, false);
      if (l + 1 == L) break;
      skips.push_back(y);
      y = conv(p + ".down", g.pool(y), s.down.conv, s.down.prelu, 1, -1);
    }
    for (int l = L - 2; l >= 0; --l) {
      const ScaleLevel& s = n.scales[static_cast<size_t>(l)];
      const std::string p = "levels." + std::to_string(l);
      y = g.conv(p + ".up", {g.upsample(y), skips[static_cast<size_t>(l)]}, s.up.conv.out, 3, s.up.conv.weight,
                 s.up.conv.bias, Activation::PReLU, s.up.prelu);
      y = blocks(p + ".dec.", y, s.dec, false);
    }
  }
  y = conv("tail", y, n.tail, {}, 1, head);
  int skip = -1;
  if (n.arch.input_skip) {
    const int c = n.arch.in_channels();
    std::vector<float> select(static_cast<size_t>(3 * c), 0.0f);
    for (int k = 0; k < 3; ++k) select[static_cast<size_t>(k * c + n.arch.skip_plane() + k)] = 1.0f;
    skip = g.conv("input_skip", {input}, 3, 1, select, {}, Activation::None);
  }
  conv("out", y, n.out, {}, 1, skip);
  return g;
}

void set_weights_from_graph(Network& n, const Graph& g) {
  std::map<std::string, int> by_name;
  for (int i = 0; i < g.size(); ++i)
    if (g.op(i).kind == OpKind::Conv) by_name[g.op(i).name] = i;
  auto take = [&](const std::string& name, Conv3x3& c, std::vector<float>* prelu) {
    const auto it = by_name.find(name);
    if (it == by_name.end()) throw std::invalid_argument("the graph has no conv " + name);
    const GraphOp& op = g.op(it->second);
    if (op.weight.size() != c.weight.size() || op.bias.size() != c.bias.size() ||
        op.slopes.size() != (prelu ? prelu->size() : 0))
      throw std::invalid_argument("conv " + name + ": the graph's sizes differ from the network's");
    c.weight = op.weight;
    c.bias = op.bias;
    if (prelu) *prelu = op.slopes;
  };
  auto blocks = [&](const std::string& prefix, std::vector<ResBlock>& bs) {
    for (size_t b = 0; b < bs.size(); ++b) {
      take(prefix + std::to_string(b) + ".conv1", bs[b].conv1, &bs[b].prelu);
      take(prefix + std::to_string(b) + ".conv2", bs[b].conv2, nullptr);
    }
  };
  take("head", n.head, &n.head_prelu);
  blocks("blocks.", n.blocks);
  for (size_t l = 0; l < n.scales.size(); ++l) {
    ScaleLevel& s = n.scales[l];
    const std::string p = "levels." + std::to_string(l);
    blocks(p + ".enc.", s.enc);
    if (l + 1 == n.scales.size()) break;
    take(p + ".down", s.down.conv, &s.down.prelu);
    take(p + ".up", s.up.conv, &s.up.prelu);
    blocks(p + ".dec.", s.dec);
  }
  take("tail", n.tail, nullptr);
  take("out", n.out, nullptr);
}

namespace {

Conv3x3 random_conv(int in, int out, std::mt19937& rng, bool bias) {
  Conv3x3 c;
  c.in = in;
  c.out = out;
  // He initialisation for PReLU networks: std = sqrt(2 / fan_in).
  std::normal_distribution<float> w(0.0f, std::sqrt(2.0f / static_cast<float>(9 * in)));
  std::uniform_real_distribution<float> b(-0.1f, 0.1f);
  c.weight.resize(static_cast<size_t>(out * in * 9));
  for (float& v : c.weight) v = w(rng);
  c.bias.resize(static_cast<size_t>(out));
  for (float& v : c.bias) v = bias ? b(rng) : 0.0f;
  return c;
}

std::vector<float> random_prelu(int n, std::mt19937& rng) {
  std::uniform_real_distribution<float> a(0.05f, 0.35f);
  std::vector<float> v(static_cast<size_t>(n));
  for (float& x : v) x = a(rng);
  return v;
}

}  // namespace

Network random_network(const Architecture& arch, uint32_t seed) {
  std::mt19937 rng(seed);
  Network n;
  n.arch = arch;
  n.head = random_conv(arch.in_channels(), arch.level_width(0), rng, true);
  n.head_prelu = random_prelu(arch.level_width(0), rng);
  auto block = [&](int w) {
    ResBlock blk;
    blk.conv1 = random_conv(w, w, rng, true);
    blk.prelu = random_prelu(w, rng);
    blk.conv2 = random_conv(w, w, rng, true);
    // Scale the residual branch down so activations stay O(1) through deep random networks.
    for (float& v : blk.conv2.weight) v *= 0.2f;
    return blk;
  };
  if (!arch.multiscale()) {
    for (int b = 0; b < arch.blocks; ++b) n.blocks.push_back(block(arch.width));
  } else {
    const int L = static_cast<int>(arch.levels.size());
    n.scales.resize(static_cast<size_t>(L));
    for (int l = 0; l < L; ++l) {
      ScaleLevel& s = n.scales[static_cast<size_t>(l)];
      const int w = arch.level_width(l);
      for (int b = 0; b < arch.levels[static_cast<size_t>(l)]; ++b) s.enc.push_back(block(w));
      if (l + 1 == L) break;
      const int below = arch.level_width(l + 1);
      s.down = {random_conv(w, below, rng, true), random_prelu(below, rng)};
      s.up = {random_conv(below + w, w, rng, true), random_prelu(w, rng)};
      for (int b = 0; b < arch.levels[static_cast<size_t>(l)]; ++b) s.dec.push_back(block(w));
    }
  }
  n.tail = random_conv(arch.level_width(0), arch.level_width(0), rng, true);
  n.out = random_conv(arch.level_width(0), 3, rng, true);
  return n;
}

}  // namespace residue::nn
