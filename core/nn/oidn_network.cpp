#include "core/nn/oidn_network.h"

#include "core/nn/safetensors.h"
#include "core/util/error.h"

namespace residue::nn {
namespace {

class Builder {
 public:
  Builder(const TzaFile& w, std::string where) : w_(w), where_(std::move(where)) {}

  // conv(name, inputs...) with ReLU: its output channels are what the weights say, the input channels must be
  // the sum of the inputs' (a concat conv takes them in order).
  int conv(const std::string& name, std::vector<int> inputs) {
    int in = 0;
    for (int x : inputs) in += g.op(x).channels;
    const TzaTensor& wt = tensor(name + ".weight");
    if (wt.shape.size() != 4 || wt.shape[1] != in || wt.shape[2] != 3 || wt.shape[3] != 3 || wt.shape[0] <= 0)
      throw Error(ErrorKind::Input, where_ + ": tensor \"" + name + ".weight\" has shape " + shape_to_string(wt.shape) +
                                        "; expected [out, " + std::to_string(in) + ", 3, 3]");
    const int out = static_cast<int>(wt.shape[0]);
    const TzaTensor& b = tensor(name + ".bias");
    if (b.shape != std::vector<int64_t>{out})
      throw Error(ErrorKind::Input, where_ + ": tensor \"" + name + ".bias\" has shape " + shape_to_string(b.shape) +
                                        "; expected [" + std::to_string(out) + "]");
    check_finite(wt.values, where_, name + ".weight");
    check_finite(b.values, where_, name + ".bias");
    return g.conv(name, std::move(inputs), out, 3, wt.values, b.values, Activation::ReLU);
  }

  Graph g;

 private:
  const TzaTensor& tensor(const std::string& name) const {
    auto it = w_.tensors.find(name);
    if (it == w_.tensors.end()) throw Error(ErrorKind::Input, where_ + ": tensor \"" + name + "\" is missing");
    return it->second;
  }
  const TzaFile& w_;
  std::string where_;
};

}  // namespace

bool oidn_is_large(const TzaFile& weights) { return weights.tensors.count("enc_conv1b.weight") > 0; }

const char* oidn_network_name(const Graph& graph) {
  // The large variant's first conv is enc_conv1a (the base UNet's is enc_conv0); op 0 is the input.
  return graph.size() > 1 && graph.op(1).name == "enc_conv1a" ? "UNetLarge" : "UNet";
}

Graph oidn_graph(const TzaFile& weights, int input_channels, const std::string& where) {
  Builder b(weights, where);
  const int in = b.g.input(input_channels);
  int x, p1, p2, p3, p4;
  if (oidn_is_large(weights)) {
    x = b.conv("enc_conv1a", {in});
    p1 = b.g.pool(b.conv("enc_conv1b", {x}));
    x = b.conv("enc_conv2a", {p1});
    p2 = b.g.pool(b.conv("enc_conv2b", {x}));
    x = b.conv("enc_conv3a", {p2});
    p3 = b.g.pool(b.conv("enc_conv3b", {x}));
    x = b.conv("enc_conv4a", {p3});
    p4 = b.g.pool(b.conv("enc_conv4b", {x}));
  } else {
    x = b.conv("enc_conv0", {in});
    p1 = b.g.pool(b.conv("enc_conv1", {x}));
    p2 = b.g.pool(b.conv("enc_conv2", {p1}));
    p3 = b.g.pool(b.conv("enc_conv3", {p2}));
    p4 = b.g.pool(b.conv("enc_conv4", {p3}));
  }
  x = b.conv("enc_conv5a", {p4});
  x = b.conv("enc_conv5b", {x});
  x = b.conv("dec_conv4a", {b.g.upsample(x), p3});
  x = b.conv("dec_conv4b", {x});
  x = b.conv("dec_conv3a", {b.g.upsample(x), p2});
  x = b.conv("dec_conv3b", {x});
  x = b.conv("dec_conv2a", {b.g.upsample(x), p1});
  x = b.conv("dec_conv2b", {x});
  x = b.conv("dec_conv1a", {b.g.upsample(x), in});
  x = b.conv("dec_conv1b", {x});
  x = b.conv(oidn_is_large(weights) ? "dec_conv1c" : "dec_conv0", {x});
  if (b.g.op(x).channels != 3)
    throw Error(ErrorKind::Input, where + ": the last conv has " + std::to_string(b.g.op(x).channels) +
                                      " output channels; expected 3");
  return b.g;
}

}  // namespace residue::nn
