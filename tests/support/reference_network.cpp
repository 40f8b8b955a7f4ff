#include "support/reference_network.h"

#include <algorithm>
#include <cmath>

namespace residue::testing {

Tensor64 to_tensor(const Image& image) {
  Tensor64 t{image.height(), image.width(), image.channels(), {}};
  t.v.assign(image.data(), image.data() + image.size());
  return t;
}

Tensor64 naive_conv3x3(const Tensor64& in, const nn::Conv3x3& conv, int dilation) {
  Tensor64 out{in.h, in.w, conv.out, std::vector<double>(static_cast<size_t>(in.h * in.w * conv.out))};
  for (int64_t y = 0; y < in.h; ++y)
    for (int64_t x = 0; x < in.w; ++x)
      for (int o = 0; o < conv.out; ++o) {
        double sum = conv.bias.empty() ? 0.0 : conv.bias[static_cast<size_t>(o)];
        for (int ky = 0; ky < 3; ++ky)
          for (int kx = 0; kx < 3; ++kx) {
            const int64_t sy = y + (ky - 1) * dilation, sx = x + (kx - 1) * dilation;
            if (sy < 0 || sy >= in.h || sx < 0 || sx >= in.w) continue;
            for (int i = 0; i < conv.in; ++i) sum += static_cast<double>(conv.w(o, i, ky, kx)) * in.at(sy, sx, i);
          }
        out.at(y, x, o) = sum;
      }
  return out;
}

namespace {
void prelu(Tensor64& t, const std::vector<float>& slopes) {
  for (size_t i = 0; i < t.v.size(); ++i)
    if (t.v[i] < 0) t.v[i] *= slopes[i % static_cast<size_t>(t.c)];
}
void add(Tensor64& t, const Tensor64& other) {
  for (size_t i = 0; i < t.v.size(); ++i) t.v[i] += other.v[i];
}
}  // namespace

Tensor64 naive_forward(const nn::Network& net, const Image& input) {
  Tensor64 h = naive_conv3x3(to_tensor(input), net.head);
  prelu(h, net.head_prelu);
  Tensor64 y = h;
  for (size_t i = 0; i < net.blocks.size(); ++i) {
    const auto& b = net.blocks[i];
    const int d = net.arch.dilation(static_cast<int>(i));
    Tensor64 t = naive_conv3x3(y, b.conv1, d);
    prelu(t, b.prelu);
    Tensor64 r = naive_conv3x3(t, b.conv2, d);
    add(r, y);
    y = std::move(r);
  }
  Tensor64 tail = naive_conv3x3(y, net.tail);
  add(tail, h);
  Tensor64 out = naive_conv3x3(tail, net.out);
  if (net.arch.input_skip)
    for (int64_t p = 0; p < out.h * out.w; ++p)
      for (int k = 0; k < 3; ++k)
        out.v[static_cast<size_t>(p * 3 + k)] += input.data()[p * input.channels() + net.arch.skip_plane() + k];
  return out;
}

double max_relative_error(const Image& a, const Tensor64& b, double floor) {
  double scale = floor, err = 0;
  for (double v : b.v) scale = std::max(scale, std::abs(v));
  for (size_t i = 0; i < b.v.size(); ++i) err = std::max(err, std::abs(static_cast<double>(a.data()[i]) - b.v[i]));
  return err / scale;
}

Tensor64 naive_graph(const nn::Graph& g, const Image& input) {
  std::vector<Tensor64> v(static_cast<size_t>(g.size()));
  for (int i = 0; i < g.size(); ++i) {
    const nn::GraphOp& op = g.op(i);
    Tensor64& out = v[static_cast<size_t>(i)];
    switch (op.kind) {
      case nn::OpKind::Input: out = to_tensor(input); break;
      case nn::OpKind::Conv: {
        const Tensor64& first = v[static_cast<size_t>(op.inputs[0])];
        out = Tensor64{first.h, first.w, op.channels, std::vector<double>(static_cast<size_t>(first.h * first.w * op.channels))};
        const int r = op.dilation * (op.kernel / 2);
        for (int64_t y = 0; y < out.h; ++y)
          for (int64_t x = 0; x < out.w; ++x)
            for (int o = 0; o < op.channels; ++o) {
              double sum = op.bias[static_cast<size_t>(o)];
              int base = 0;  // the input's first channel in the concatenation
              for (int src : op.inputs) {
                const Tensor64& in = v[static_cast<size_t>(src)];
                for (int ky = 0; ky < op.kernel; ++ky)
                  for (int kx = 0; kx < op.kernel; ++kx) {
                    const int64_t sy = y + ky * op.dilation - r, sx = x + kx * op.dilation - r;
                    if (sy < 0 || sy >= in.h || sx < 0 || sx >= in.w) continue;
                    for (int c = 0; c < in.c; ++c) sum += static_cast<double>(op.w(o, base + c, ky, kx)) * in.at(sy, sx, c);
                  }
                base += in.c;
              }
              if (op.activation == nn::Activation::ReLU) sum = std::max(sum, 0.0);
              if (op.activation == nn::Activation::PReLU && sum < 0) sum *= op.slopes[static_cast<size_t>(o)];
              if (op.residual >= 0) sum += v[static_cast<size_t>(op.residual)].at(y, x, o);
              out.at(y, x, o) = sum;
            }
        break;
      }
      case nn::OpKind::Pool: {
        const Tensor64& in = v[static_cast<size_t>(op.inputs[0])];
        out = Tensor64{in.h / 2, in.w / 2, in.c, std::vector<double>(static_cast<size_t>(in.h / 2 * (in.w / 2) * in.c))};
        for (int64_t y = 0; y < out.h; ++y)
          for (int64_t x = 0; x < out.w; ++x)
            for (int c = 0; c < in.c; ++c)
              out.at(y, x, c) = std::max({in.at(2 * y, 2 * x, c), in.at(2 * y, 2 * x + 1, c), in.at(2 * y + 1, 2 * x, c),
                                          in.at(2 * y + 1, 2 * x + 1, c)});
        break;
      }
      case nn::OpKind::Upsample: {
        const Tensor64& in = v[static_cast<size_t>(op.inputs[0])];
        out = Tensor64{in.h * 2, in.w * 2, in.c, std::vector<double>(static_cast<size_t>(in.h * 2 * in.w * 2 * in.c))};
        for (int64_t y = 0; y < out.h; ++y)
          for (int64_t x = 0; x < out.w; ++x)
            for (int c = 0; c < in.c; ++c) out.at(y, x, c) = in.at(y / 2, x / 2, c);
        break;
      }
      case nn::OpKind::Add:
        out = v[static_cast<size_t>(op.inputs[0])];
        add(out, v[static_cast<size_t>(op.inputs[1])]);
        break;
    }
  }
  return v[static_cast<size_t>(g.output())];
}

}  // namespace residue::testing
