#include "torch_network.h"

#include <algorithm>
#include <cstdlib>

#include "core/nn/model_file.h"
#include "core/util/error.h"

namespace residue::train {
namespace {

torch::nn::Conv2dOptions conv3x3(int in, int out, bool bias, int dilation = 1) {
  return torch::nn::Conv2dOptions(in, out, 3).padding(dilation).dilation(dilation).bias(bias);
}

// A model file's tensor as a libtorch view of its values (no copy).
torch::Tensor view_of(const nn::Tensor& t) {
  return torch::from_blob(const_cast<float*>(t.values.data()), std::vector<int64_t>(t.shape.begin(), t.shape.end()),
                          torch::kFloat32);
}

// Copies a model file's tensor into the network's, refusing another shape.
void copy_checked(const torch::Tensor& value, torch::Tensor& target, const std::string& file, const std::string& name) {
  if (value.sizes() != target.sizes())
    throw Error(ErrorKind::Input, file + ": tensor '" + name + "' has the wrong shape for this network");
  target.copy_(value);
}

// A model file's metadata value, or `fallback` where it has none.
std::string metadata_or(const nn::SafetensorsFile& file, const std::string& key, const std::string& fallback = "") {
  const auto it = file.metadata.find(key);
  return it == file.metadata.end() ? fallback : it->second;
}

// Refuses a file with a tensor the network has no parameter or buffer for (a network of another shape).
void require_a_place_for_every_tensor(ResidueNet& net, const nn::SafetensorsFile& source, const std::string& file) {
  const auto params = net->named_parameters(), buffers = net->named_buffers();
  for (const auto& [name, t] : source.tensors)
    if (!params.contains(name) && !buffers.contains(name))
      throw Error(ErrorKind::Input, file + ": tensor '" + name + "' has no place in " + net->arch.to_string());
}

// Replaces the running statistics of `norms` by their plain average over `batches` forward passes of `net` (in its
// current mode: the other batch norms keep theirs), then restores each one's momentum. Leaves `norms` training.
void measure_batch_norms(ResidueNet& net, const std::vector<torch::nn::BatchNorm2dImpl*>& norms,
                         const std::function<torch::Tensor()>& next_batch, int batches) {
  std::vector<c10::optional<double>> momentum;
  for (auto* bn : norms) {
    momentum.push_back(bn->options.momentum());
    bn->reset_running_stats();
    bn->options.momentum(c10::nullopt);  // a cumulative average over the batches below
    bn->train();
  }
  {
    torch::NoGradGuard no_grad;
    for (int i = 0; i < batches; ++i) net->forward(next_batch());
  }
  for (size_t i = 0; i < norms.size(); ++i) norms[i]->options.momentum(momentum[i]);
}

}  // namespace

ResBlockImpl::ResBlockImpl(int width, int dilation) {
  conv1 = register_module("conv1", torch::nn::Conv2d(conv3x3(width, width, false, dilation)));
  bn1 = register_module("bn1", torch::nn::BatchNorm2d(width));
  prelu = register_module("prelu", torch::nn::PReLU(torch::nn::PReLUOptions().num_parameters(width)));
  conv2 = register_module("conv2", torch::nn::Conv2d(conv3x3(width, width, false, dilation)));
  bn2 = register_module("bn2", torch::nn::BatchNorm2d(width));
}

torch::Tensor ResBlockImpl::forward(const torch::Tensor& x) {
  return x + bn2(conv2(prelu(bn1(conv1(x)))));
}

HeadImpl::HeadImpl(int in, int width) {
  conv = register_module("conv", torch::nn::Conv2d(conv3x3(in, width, true)));
  prelu = register_module("prelu", torch::nn::PReLU(torch::nn::PReLUOptions().num_parameters(width)));
}

TailImpl::TailImpl(int width) {
  conv = register_module("conv", torch::nn::Conv2d(conv3x3(width, width, false)));
  bn = register_module("bn", torch::nn::BatchNorm2d(width));
}

OutImpl::OutImpl(int width) { conv = register_module("conv", torch::nn::Conv2d(conv3x3(width, 3, true))); }

ConvBnPReluImpl::ConvBnPReluImpl(int in, int out) {
  conv = register_module("conv", torch::nn::Conv2d(conv3x3(in, out, false)));
  bn = register_module("bn", torch::nn::BatchNorm2d(out));
  prelu = register_module("prelu", torch::nn::PReLU(torch::nn::PReLUOptions().num_parameters(out)));
}

torch::Tensor ConvBnPReluImpl::forward(const torch::Tensor& x) { return prelu(bn(conv(x))); }

ScaleLevelImpl::ScaleLevelImpl(const nn::Architecture& a, int l) {
  const int w = a.level_width(l), n = a.levels[static_cast<size_t>(l)];
  enc = register_module("enc", torch::nn::ModuleList());
  for (int b = 0; b < n; ++b) enc->push_back(ResBlock(w, 1));
  if (l + 1 == static_cast<int>(a.levels.size())) return;  // the bottom
  down = register_module("down", ConvBnPRelu(w, a.level_width(l + 1)));
  up = register_module("up", ConvBnPRelu(a.level_width(l + 1) + w, w));
  dec = register_module("dec", torch::nn::ModuleList());
  for (int b = 0; b < n; ++b) dec->push_back(ResBlock(w, 1));
}

ResidueNetImpl::ResidueNetImpl(const nn::Architecture& a) : arch(a) {
  const int w = a.level_width(0);
  head = register_module("head", Head(a.in_channels(), w));
  if (!a.multiscale()) {
    blocks = register_module("blocks", torch::nn::ModuleList());
    for (int b = 0; b < a.blocks; ++b) blocks->push_back(ResBlock(a.width, a.dilation(b)));
  } else {
    levels = register_module("levels", torch::nn::ModuleList());
    for (int l = 0; l < static_cast<int>(a.levels.size()); ++l) levels->push_back(ScaleLevel(a, l));
  }
  tail = register_module("tail", Tail(w));
  out = register_module("out", Out(w));
}

torch::Tensor ResidueNetImpl::forward(const torch::Tensor& x) {
  const torch::Tensor h = head->prelu(head->conv(x));
  torch::Tensor y = h;
  if (!arch.multiscale()) {
    for (const auto& m : *blocks) y = m->as<ResBlock>()->forward(y);
  } else {
    const auto L = levels->size();
    std::vector<torch::Tensor> skips;
    for (size_t l = 0; l < L; ++l) {
      auto* level = levels[l]->as<ScaleLevel>();
      for (const auto& m : *level->enc) y = m->as<ResBlock>()->forward(y);
      if (l + 1 == L) break;
      skips.push_back(y);
      y = level->down->forward(torch::max_pool2d(y, 2, 2));
    }
    for (size_t l = L - 1; l-- > 0;) {
      auto* level = levels[l]->as<ScaleLevel>();
      const torch::Tensor up = torch::upsample_nearest2d(y, {y.size(2) * 2, y.size(3) * 2});
      y = level->up->forward(torch::cat({up, skips[l]}, 1));
      for (const auto& m : *level->dec) y = m->as<ResBlock>()->forward(y);
    }
  }
  y = tail->bn(tail->conv(y)) + h;
  if (arch.input_skip) return out->conv(y) + x.slice(1, arch.skip_plane(), arch.skip_plane() + 3);  // log colour planes
  return out->conv(y);
}

void initialise(ResidueNet& net) {
  torch::NoGradGuard no_grad;
  for (auto& m : net->modules(/*include_self=*/false)) {
    if (auto* conv = m->as<torch::nn::Conv2d>()) {
      // He et al. 2015 for PReLU (a = 0.25): std = sqrt(2 / ((1 + a^2) fan_in)).
      torch::nn::init::kaiming_normal_(conv->weight, 0.25, torch::kFanIn, torch::kLeakyReLU);
      if (conv->options.bias()) conv->bias.zero_();
    }
  }
  // A post-correction network that adds its prior's output starts as that output: its correction (the output
  // conv) at zero, so training can only move away from the prior where that lowers the loss.
  if (!net->arch.prior.empty() && net->arch.input_skip) {
    net->out->conv->weight.zero_();
    if (net->out->conv->options.bias()) net->out->conv->bias.zero_();
  }
}

void initialise_from(ResidueNet& net, const nn::SafetensorsFile& source, const std::filesystem::path& path) {
  const std::string file = path.string();
  auto meta = [&](const std::string& key, const std::string& fallback) { return metadata_or(source, key, fallback); };
  const auto source_features = feature_set_from_string(meta("residue.features", "full"));
  if (!source_features) throw Error(ErrorKind::Input, file + ": unknown feature set '" + meta("residue.features", "") + "'");
  const std::string dilations = net->arch.max_dilation() > 1 ? nn::dilations_to_string(net->arch.dilations) : "";
  const std::string levels = net->arch.multiscale() ? nn::ints_to_string(net->arch.levels) : "";
  const std::string widths = net->arch.multiscale() ? nn::ints_to_string(net->arch.widths) : "";
  if (meta("residue.blocks", "") != std::to_string(net->arch.blocks) || meta("residue.width", "") != std::to_string(net->arch.width) ||
      meta("residue.dilations", "") != dilations || meta("residue.levels", "") != levels || meta("residue.widths", "") != widths)
    throw Error(ErrorKind::Input, file + ": a " + meta("residue.blocks", "?") + "/" + meta("residue.width", "?") +
                                      " network cannot initialise a " + std::to_string(net->arch.blocks) + "/" +
                                      std::to_string(net->arch.width) + " one (blocks, width and dilations must match)");
  // The head's input planes are matched by name, so a model starts from one with fewer inputs (a temporal model
  // from a still's: the neighbours' planes start at zero weight, and it denoises as its source did).
  nn::Architecture source_arch;
  source_arch.features = *source_features;
  source_arch.prior = meta("residue.prior", "");
  source_arch.temporal = std::atoi(meta("residue.temporal", "0").c_str());
  const std::vector<std::string> from = nn::input_planes(source_arch), to = nn::input_planes(net->arch);

  torch::NoGradGuard no_grad;
  auto copy = [&](const std::string& name, torch::Tensor& target) {
    if (name.find("num_batches_tracked") != std::string::npos) return;
    const auto it = source.tensors.find(name);
    if (it == source.tensors.end()) throw Error(ErrorKind::Input, file + ": no tensor '" + name + "'");
    torch::Tensor value = view_of(it->second);
    if (name == "head.conv.weight" && value.dim() == 4 && value.size(1) == static_cast<int64_t>(from.size())) {
      torch::Tensor matched = torch::zeros({value.size(0), static_cast<int64_t>(to.size()), value.size(2), value.size(3)});
      for (size_t c = 0; c < to.size(); ++c) {
        const auto src = std::find(from.begin(), from.end(), to[c]);
        if (src != from.end()) matched.select(1, static_cast<int64_t>(c)).copy_(value.select(1, src - from.begin()));
      }
      value = matched;
    }
    copy_checked(value, target, file, name);
  };
  for (auto& p : net->named_parameters()) copy(p.key(), p.value());
  for (auto& b : net->named_buffers()) copy(b.key(), b.value());
}

void grow_from(ResidueNet& net, const nn::SafetensorsFile& source, const std::filesystem::path& path,
               const std::function<torch::Tensor()>& next_batch, int bn_batches) {
  const std::string file = path.string();
  const nn::Architecture& a = net->arch;
  const int L = static_cast<int>(a.levels.size()), bottom = L - 2;  // the source's bottom level
  auto meta = [&](const std::string& key) { return metadata_or(source, key); };
  std::vector<int> levels, widths;  // the source's: every level but the new bottom
  for (int l = 0; l + 1 < L; ++l) {
    levels.push_back(a.levels[static_cast<size_t>(l)]);
    widths.push_back(a.level_width(l));
  }
  if (L < 3 || meta("residue.levels") != nn::ints_to_string(levels) ||
      meta("residue.widths") != nn::ints_to_string(widths) || meta("residue.features") != to_string(a.features))
    throw Error(ErrorKind::Input, file + ": a " + meta("residue.levels") + "/" + meta("residue.widths") + " " +
                                      meta("residue.features") + " network cannot grow into " + a.to_string() +
                                      " (the same levels, widths and features plus one level below)");
  torch::NoGradGuard no_grad;
  std::vector<torch::nn::BatchNorm2dImpl*> fresh;  // batch norms the source has no statistics for
  for (auto& m : net->named_modules("", /*include_self=*/false))
    if (auto* bn = m.value()->as<torch::nn::BatchNorm2d>())
      if (!source.tensors.count(m.key() + ".running_mean")) fresh.push_back(bn);
  auto copy = [&](const std::string& name, torch::Tensor& target) {  // the new level's tensors are not in the file
    const auto it = source.tensors.find(name);
    if (it != source.tensors.end() && name.find("num_batches_tracked") == std::string::npos)
      copy_checked(view_of(it->second), target, file, name);
  };
  for (auto& p : net->named_parameters()) copy(p.key(), p.value());
  for (auto& b : net->named_buffers()) copy(b.key(), b.value());
  require_a_place_for_every_tensor(net, source, file);

  auto* level = net->levels[static_cast<size_t>(bottom)]->as<ScaleLevel>();
  const int64_t w = a.level_width(bottom), below = a.level_width(bottom + 1);
  auto& up = *level->up;
  up.conv->weight.zero_();
  for (int64_t c = 0; c < w; ++c) up.conv->weight[c][below + c][1][1] = 1;  // cat(upsampled, skip): skip second
  up.bn->weight.fill_(1);
  up.bn->bias.zero_();
  up.bn->running_mean.zero_();
  up.bn->running_var.fill_(1 - up.bn->options.eps());  // (x - 0) / sqrt(var + eps) = x
  up.prelu->weight.fill_(1);
  fresh.erase(std::remove(fresh.begin(), fresh.end(), up.bn.get()), fresh.end());
  for (const auto& m : *level->dec) {
    auto* block = m->as<ResBlock>();
    block->bn2->weight.zero_();
    block->bn2->bias.zero_();
  }

  // The new batch norms' statistics, measured with the rest of the network as inference runs it.
  const bool was_training = net->is_training();
  net->eval();
  measure_batch_norms(net, fresh, next_batch, bn_batches);
  net->train(was_training);
}

void widen_from(ResidueNet& net, const nn::SafetensorsFile& source, const std::filesystem::path& path,
                const std::function<torch::Tensor()>& next_batch, int bn_batches) {
  const std::string file = path.string();
  const nn::Architecture& a = net->arch;
  auto meta = [&](const std::string& key) { return metadata_or(source, key); };
  // The source's architecture is this one at the source's widths: every residue.* key must then agree.
  nn::Architecture narrow = a;
  std::vector<int> old_widths;
  if (const auto w = nn::parse_ints(meta(a.multiscale() ? "residue.widths" : "residue.width"), 1, 4096)) old_widths = *w;
  if (a.multiscale()) narrow.widths = old_widths;  // residue.width is then the first level's (model_file.cpp)
  if (!old_widths.empty()) narrow.width = old_widths[0];
  std::map<std::string, std::string> expected;
  if (!old_widths.empty()) nn::write_architecture_metadata(narrow, expected);
  bool same = !old_widths.empty() && old_widths.size() == (a.multiscale() ? a.widths.size() : 1u);
  for (const auto& [key, value] : expected) same = same && meta(key) == value;
  for (size_t l = 0; same && l < old_widths.size(); ++l) same = old_widths[l] <= a.level_width(static_cast<int>(l));
  if (!same)
    throw Error(ErrorKind::Input, file + ": a " + meta("residue.blocks") + "/" + meta("residue.width") + " " +
                                      meta("residue.levels") + "/" + meta("residue.widths") + " " +
                                      meta("residue.features") + " network cannot widen into " + a.to_string() +
                                      " (the same architecture, each level at least as wide)");
  auto old_width = [&](int l) { return old_widths[static_cast<size_t>(l)]; };

  torch::NoGradGuard no_grad;
  // Where a source tensor's channels go, per dimension: runs of (from, to, count). Every dimension is a prefix
  // but an up step's input, cat(upsampled level below, skip): two runs.
  using Runs = std::vector<std::array<int64_t, 3>>;
  auto input_runs = [&](const std::string& name, int64_t count) -> Runs {
    for (int l = 0; a.multiscale() && l + 1 < static_cast<int>(a.levels.size()); ++l)
      if (name == "levels." + std::to_string(l) + ".up.conv.weight")
        return {{0, 0, old_width(l + 1)}, {old_width(l + 1), a.level_width(l + 1), old_width(l)}};
    return {{0, 0, count}};
  };
  std::vector<torch::nn::BatchNorm2dImpl*> widened;  // batch norms with new channels, and their names
  std::vector<std::string> widened_names;
  for (auto& m : net->named_modules("", /*include_self=*/false))
    if (auto* bn = m.value()->as<torch::nn::BatchNorm2d>())
      if (const auto it = source.tensors.find(m.key() + ".running_mean");
          it != source.tensors.end() && it->second.shape[0] < bn->options.num_features()) {
        widened.push_back(bn);
        widened_names.push_back(m.key());
      }
  auto place = [&](const std::string& name, torch::Tensor& target) {
    if (name.find("num_batches_tracked") != std::string::npos) return;
    const auto it = source.tensors.find(name);
    if (it == source.tensors.end()) throw Error(ErrorKind::Input, file + ": no tensor '" + name + "'");
    const torch::Tensor value = view_of(it->second);
    bool fits = value.dim() == target.dim();
    for (int64_t d = 0; fits && d < value.dim(); ++d)
      fits = value.size(d) <= target.size(d) && (d < 2 || value.size(d) == target.size(d));
    if (!fits) throw Error(ErrorKind::Input, file + ": tensor '" + name + "' does not fit the wider network");
    const int64_t outs = value.size(0);
    if (value.dim() == 1) {
      target.slice(0, 0, outs).copy_(value);
      return;
    }
    torch::Tensor old_rows = target.slice(0, 0, outs);
    old_rows.zero_();  // the old outputs read nothing from the new inputs
    for (const auto& [from, to, count] : input_runs(name, value.size(1)))
      old_rows.slice(1, to, to + count).copy_(value.slice(1, from, from + count));
  };
  for (auto& p : net->named_parameters()) place(p.key(), p.value());
  for (auto& b : net->named_buffers()) place(b.key(), b.value());
  require_a_place_for_every_tensor(net, source, file);

  // The new channels' statistics, measured with the network as inference runs it; then the source's back into the
  // old channels.
  const bool was_training = net->is_training();
  net->eval();
  measure_batch_norms(net, widened, next_batch, bn_batches);
  for (size_t i = 0; i < widened.size(); ++i) {  // place() found both in the file
    const torch::Tensor mean = view_of(source.tensors.at(widened_names[i] + ".running_mean"));
    const torch::Tensor var = view_of(source.tensors.at(widened_names[i] + ".running_var"));
    widened[i]->running_mean.slice(0, 0, mean.size(0)).copy_(mean);
    widened[i]->running_var.slice(0, 0, var.size(0)).copy_(var);
  }
  net->train(was_training);
}

namespace {

std::vector<torch::nn::BatchNorm2dImpl*> batch_norms(ResidueNet& net) {
  std::vector<torch::nn::BatchNorm2dImpl*> norms;
  for (const auto& m : net->modules(/*include_self=*/false))
    if (auto* bn = dynamic_cast<torch::nn::BatchNorm2dImpl*>(m.get())) norms.push_back(bn);
  return norms;
}

}  // namespace

void recalibrate_batch_norm(ResidueNet& net, const std::function<torch::Tensor()>& next_batch, int batches) {
  const bool was_training = net->is_training();
  net->train();
  measure_batch_norms(net, batch_norms(net), next_batch, batches);
  net->train(was_training);
}

void freeze_batch_norm(ResidueNet& net) {
  for (auto* bn : batch_norms(net)) bn->eval();
}

void use_channels_last(ResidueNet& net) {
  torch::NoGradGuard no_grad;
  for (auto& p : net->parameters())
    if (p.dim() == 4) p.set_data(p.data().contiguous(at::MemoryFormat::ChannelsLast));
}

torch::Tensor to_channels_last(const torch::Tensor& batch) { return batch.contiguous(at::MemoryFormat::ChannelsLast); }

nn::SafetensorsFile export_model(ResidueNet& net, std::map<std::string, std::string> metadata) {
  nn::SafetensorsFile f;
  f.metadata = std::move(metadata);
  nn::write_architecture_metadata(net->arch, f.metadata);
  f.metadata["residue.bn_eps"] = "1e-05";
  auto put = [&](const std::string& name, const torch::Tensor& t) {
    if (name.find("num_batches_tracked") != std::string::npos) return;
    const torch::Tensor c = t.detach().to(torch::kCPU, torch::kFloat32).contiguous();
    nn::Tensor out;
    out.shape.assign(c.sizes().begin(), c.sizes().end());
    out.values.assign(c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
    f.tensors[name] = std::move(out);
  };
  for (const auto& p : net->named_parameters()) put(p.key(), p.value());
  for (const auto& b : net->named_buffers()) put(b.key(), b.value());
  return f;
}

}  // namespace residue::train
