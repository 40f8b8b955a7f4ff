#include "core/nn/graph.h"

#include <algorithm>
#include <stdexcept>

#include "core/util/error.h"

namespace residue::nn {

int Graph::push(GraphOp op) {
  ops_.push_back(std::move(op));
  return size() - 1;
}

void Graph::check_value(int x, const char* what) const {
  if (x < 0 || x >= size())
    throw std::invalid_argument(std::string(what) + ": value " + std::to_string(x) + " does not exist (graph has " +
                                std::to_string(size()) + " ops)");
}

int Graph::input(int channels) {
  if (channels <= 0) throw std::invalid_argument("graph input: channels must be positive");
  for (const GraphOp& o : ops_)
    if (o.kind == OpKind::Input) throw std::invalid_argument("graph input: the graph has an input already");
  GraphOp op;
  op.kind = OpKind::Input;
  op.name = "input";
  op.channels = channels;
  return push(std::move(op));
}

int Graph::conv(std::string name, std::vector<int> inputs, int out_channels, int kernel, std::vector<float> weight,
                std::vector<float> bias, Activation activation, std::vector<float> slopes, int dilation, int residual) {
  const std::string where = "conv " + name;
  if (inputs.empty()) throw std::invalid_argument(where + ": no input");
  if (kernel != 1 && kernel != 3) throw std::invalid_argument(where + ": kernel must be 1 or 3");
  if (dilation < 1) throw std::invalid_argument(where + ": dilation must be >= 1");
  if (out_channels <= 0) throw std::invalid_argument(where + ": output channels must be positive");
  GraphOp op;
  op.kind = OpKind::Conv;
  op.name = std::move(name);
  op.level = -1;
  for (int x : inputs) {
    check_value(x, where.c_str());
    if (op.level >= 0 && op.level != this->op(x).level)
      throw std::invalid_argument(where + ": inputs at different resolutions");
    op.level = this->op(x).level;
    op.in_channels += this->op(x).channels;
  }
  op.inputs = std::move(inputs);
  op.channels = out_channels;
  op.kernel = kernel;
  op.dilation = dilation;
  const size_t expected = static_cast<size_t>(out_channels) * static_cast<size_t>(op.in_channels) *
                          static_cast<size_t>(kernel * kernel);
  if (weight.size() != expected)
    throw std::invalid_argument(where + ": " + std::to_string(weight.size()) + " weights; expected " +
                                std::to_string(expected));
  if (bias.empty()) bias.assign(static_cast<size_t>(out_channels), 0.0f);
  if (bias.size() != static_cast<size_t>(out_channels)) throw std::invalid_argument(where + ": bias size");
  op.weight = std::move(weight);
  op.bias = std::move(bias);
  op.activation = activation;
  if (activation == Activation::PReLU && slopes.size() != static_cast<size_t>(out_channels))
    throw std::invalid_argument(where + ": PReLU needs one slope per output channel");
  if (activation != Activation::PReLU) slopes.clear();
  op.slopes = std::move(slopes);
  if (residual >= 0) {
    check_value(residual, where.c_str());
    if (this->op(residual).channels != out_channels || this->op(residual).level != op.level)
      throw std::invalid_argument(where + ": the residual's shape differs from the output's");
    if (op.inputs.size() > 1) throw std::invalid_argument(where + ": a concat conv cannot take a residual");
  }
  op.residual = residual;
  return push(std::move(op));
}

int Graph::pool(int x) {
  check_value(x, "pool");
  GraphOp op;
  op.kind = OpKind::Pool;
  op.name = "pool(" + this->op(x).name + ")";
  op.inputs = {x};
  op.channels = this->op(x).channels;
  op.level = this->op(x).level + 1;
  if (op.level > 8) throw std::invalid_argument("pool: more than 8 levels");
  return push(std::move(op));
}

int Graph::upsample(int x) {
  check_value(x, "upsample");
  if (this->op(x).level == 0) throw std::invalid_argument("upsample: the value is at full resolution already");
  GraphOp op;
  op.kind = OpKind::Upsample;
  op.name = "upsample(" + this->op(x).name + ")";
  op.inputs = {x};
  op.channels = this->op(x).channels;
  op.level = this->op(x).level - 1;
  return push(std::move(op));
}

int Graph::add(int a, int b) {
  check_value(a, "add");
  check_value(b, "add");
  if (op(a).channels != op(b).channels || op(a).level != op(b).level)
    throw std::invalid_argument("add: the two values differ in shape");
  GraphOp o;
  o.kind = OpKind::Add;
  o.name = "add(" + op(a).name + ", " + op(b).name + ")";
  o.inputs = {a, b};
  o.channels = op(a).channels;
  o.level = op(a).level;
  return push(std::move(o));
}

void Graph::set_conv_parameters(int x, std::vector<float> weight, std::vector<float> bias, std::vector<float> slopes) {
  check_value(x, "conv parameters");
  GraphOp& o = ops_[static_cast<size_t>(x)];
  if (o.kind != OpKind::Conv || weight.size() != o.weight.size() || bias.size() != o.bias.size() ||
      slopes.size() != o.slopes.size())
    throw std::invalid_argument("conv parameters of " + o.name + ": not a conv, or sizes that differ from its own");
  o.weight = std::move(weight);
  o.bias = std::move(bias);
  o.slopes = std::move(slopes);
}

void Graph::set_output(int x) {
  check_value(x, "output");
  if (op(x).level != 0) throw std::invalid_argument("output: must be at full resolution");
  output_ = x;
}

int Graph::input_channels() const {
  for (const GraphOp& o : ops_)
    if (o.kind == OpKind::Input) return o.channels;
  return 0;
}

void Graph::check_tile(const Image& input) const {
  if (input.channels() != input_channels())
    throw Error(ErrorKind::Input, "the network expects " + std::to_string(input_channels()) +
                                      " input channels, the tile has " + std::to_string(input.channels()));
  if (input.height() % alignment() != 0 || input.width() % alignment() != 0)
    throw Error(ErrorKind::Usage, "tile " + std::to_string(input.width()) + "x" + std::to_string(input.height()) +
                                      " is not a multiple of the network's alignment " + std::to_string(alignment()));
}

int Graph::max_level() const {
  int l = 0;
  for (const GraphOp& o : ops_) l = std::max(l, o.level);
  return l;
}

int Graph::receptive_reach() const {
  // reach[i]: the farthest input pixel value i depends on, measured from the edge of its own footprint (a value
  // at level k covers 2^k x 2^k tile pixels). A conv adds its taps' reach at its level; a pool's output covers
  // exactly its inputs' footprints; an upsampled pixel sits inside its source pixel, up to 2^level from its edge.
  std::vector<int> reach(ops_.size(), 0);
  for (size_t i = 0; i < ops_.size(); ++i) {
    const GraphOp& o = ops_[i];
    int r = 0;
    for (int x : o.inputs) r = std::max(r, reach[static_cast<size_t>(x)]);
    if (o.residual >= 0) r = std::max(r, reach[static_cast<size_t>(o.residual)]);
    if (o.kind == OpKind::Conv) r += o.dilation * (o.kernel / 2) * (1 << o.level);
    if (o.kind == OpKind::Upsample) r += 1 << o.level;
    reach[i] = r;
  }
  return ops_.empty() ? 0 : reach[static_cast<size_t>(output())];
}

int Graph::halo() const {
  const int a = alignment();
  return (receptive_reach() + a - 1) / a * a;
}

double Graph::flops_per_pixel() const {
  double f = 0;
  for (const GraphOp& o : ops_)
    if (o.kind == OpKind::Conv)
      f += 2.0 * o.kernel * o.kernel * o.in_channels * o.channels / static_cast<double>(1 << (2 * o.level));
  return f;
}


std::vector<Rect> Graph::needed_regions(int64_t h, int64_t w, const Rect& needed) const {
  std::vector<Rect> region(ops_.size());
  if (ops_.empty()) return region;
  auto extent = [&](int i) { return Rect{0, 0, w >> op(i).level, h >> op(i).level}; };
  auto need = [&](int x, const Rect& r) {
    Rect& at = region[static_cast<size_t>(x)];
    at = at.united(r.intersected(extent(x)));
  };
  region[static_cast<size_t>(output())] = needed.intersected(extent(output()));
  for (int i = size() - 1; i >= 0; --i) {
    const Rect r = region[static_cast<size_t>(i)];
    if (r.empty()) continue;
    const GraphOp& o = op(i);
    switch (o.kind) {
      case OpKind::Input: break;
      case OpKind::Conv: {
        const int64_t p = o.dilation * (o.kernel / 2);
        for (int x : o.inputs) need(x, {r.x - p, r.y - p, r.width + 2 * p, r.height + 2 * p});
        if (o.residual >= 0) need(o.residual, r);
        break;
      }
      case OpKind::Pool: need(o.inputs[0], {2 * r.x, 2 * r.y, 2 * r.width, 2 * r.height}); break;
      case OpKind::Upsample: {
        const int64_t x0 = r.x / 2, y0 = r.y / 2, x1 = (r.x + r.width + 1) / 2, y1 = (r.y + r.height + 1) / 2;
        need(o.inputs[0], {x0, y0, x1 - x0, y1 - y0});
        break;
      }
      case OpKind::Add:
        for (int x : o.inputs) need(x, r);
        break;
    }
  }
  return region;
}

std::vector<int> Graph::last_uses() const {
  std::vector<int> last(ops_.size(), -1);
  for (size_t i = 0; i < ops_.size(); ++i) {
    for (int x : ops_[i].inputs) last[static_cast<size_t>(x)] = static_cast<int>(i);
    if (ops_[i].residual >= 0) last[static_cast<size_t>(ops_[i].residual)] = static_cast<int>(i);
  }
  return last;
}

std::vector<int> Graph::borders() const {
  std::vector<int> b(ops_.size(), 0);
  for (const GraphOp& o : ops_)
    if (o.kind == OpKind::Conv)
      for (int x : o.inputs) b[static_cast<size_t>(x)] = std::max(b[static_cast<size_t>(x)], o.dilation * (o.kernel / 2));
  return b;
}

std::string Graph::summary() const {
  int convs = 0, pools = 0, ups = 0, adds = 0;
  for (const GraphOp& o : ops_) {
    convs += o.kind == OpKind::Conv;
    pools += o.kind == OpKind::Pool;
    ups += o.kind == OpKind::Upsample;
    adds += o.kind == OpKind::Add;
  }
  std::string s = std::to_string(convs) + " conv";
  if (pools) s += ", " + std::to_string(pools) + " pool";
  if (ups) s += ", " + std::to_string(ups) + " upsample";
  if (adds) s += ", " + std::to_string(adds) + " add";
  s += "; " + std::to_string(max_level() + 1) + (max_level() ? " levels" : " level");
  return s;
}

}  // namespace residue::nn
