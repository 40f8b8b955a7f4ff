#include "support/naive_oidn.h"

#include <algorithm>
#include <cfloat>
#include <stdexcept>
#include <string>
#include <vector>

#include <tbb/parallel_for.h>

namespace residue::testing {
namespace {

// A feature map, H x W x C with the channel innermost (so a pixel's channels are contiguous), in double.
struct Map {
  int64_t h = 0, w = 0, c = 0;
  std::vector<double> v;
  Map() = default;
  Map(int64_t h_, int64_t w_, int64_t c_) : h(h_), w(w_), c(c_), v(static_cast<size_t>(h_ * w_ * c_), 0.0) {}
  double* px(int64_t y, int64_t x) { return v.data() + (y * w + x) * c; }
  const double* px(int64_t y, int64_t x) const { return v.data() + (y * w + x) * c; }
};

const nn::TzaTensor& tensor(const nn::TzaFile& f, const std::string& name) {
  auto it = f.tensors.find(name);
  if (it == f.tensors.end()) throw std::invalid_argument("naive_oidn: the weights have no tensor \"" + name + "\"");
  return it->second;
}

// conv(name, in): 'same' zero padding, stride 1, bias, then ReLU (every conv of OIDN's RT networks has one).
// If the weight expects more input channels than `in` has, the missing ones are zeros and contribute nothing.
Map conv_relu(const nn::TzaFile& f, const std::string& name, const Map& in) {
  const auto& wt = tensor(f, name + ".weight");
  const auto& bt = tensor(f, name + ".bias");
  if (wt.shape.size() != 4 || bt.shape.size() != 1 || bt.shape[0] != wt.shape[0])
    throw std::invalid_argument("naive_oidn: " + name + " is not an OIHW convolution with a bias");
  const int64_t O = wt.shape[0], I = wt.shape[1], KH = wt.shape[2], KW = wt.shape[3];
  if (KH != KW || KH % 2 != 1) throw std::invalid_argument("naive_oidn: " + name + " has a non-square or even kernel");
  if (I < in.c)
    throw std::invalid_argument("naive_oidn: " + name + " takes " + std::to_string(I) + " input channels, fed " +
                                std::to_string(in.c));
  const int64_t C = in.c, K = KH, pad = K / 2;

  // Weights rearranged to [ky][kx][i][o] (only the first C input channels), so that the innermost loop runs over
  // output channels, contiguous in both the weights and the accumulator. Each output is still summed in the same
  // order as the textbook loop: bias, then ky, kx, i ascending.
  std::vector<double> w(static_cast<size_t>(K * K * C * O));
  for (int64_t o = 0; o < O; ++o)
    for (int64_t i = 0; i < C; ++i)
      for (int64_t ky = 0; ky < K; ++ky)
        for (int64_t kx = 0; kx < K; ++kx)
          w[static_cast<size_t>(((ky * K + kx) * C + i) * O + o)] =
              wt.values[static_cast<size_t>(((o * I + i) * K + ky) * K + kx)];

  Map out(in.h, in.w, O);
  tbb::parallel_for(int64_t{0}, in.h, [&](int64_t y) {
    std::vector<double> acc(static_cast<size_t>(O));
    for (int64_t x = 0; x < in.w; ++x) {
      for (int64_t o = 0; o < O; ++o) acc[static_cast<size_t>(o)] = bt.values[static_cast<size_t>(o)];
      for (int64_t ky = 0; ky < K; ++ky) {
        const int64_t yy = y + ky - pad;
        if (yy < 0 || yy >= in.h) continue;
        for (int64_t kx = 0; kx < K; ++kx) {
          const int64_t xx = x + kx - pad;
          if (xx < 0 || xx >= in.w) continue;
          const double* ip = in.px(yy, xx);
          const double* wp = w.data() + (ky * K + kx) * C * O;
          double* a = acc.data();
          for (int64_t i = 0; i < C; ++i) {
            const double v = ip[i];
            const double* wi = wp + i * O;
            for (int64_t o = 0; o < O; ++o) a[o] += wi[o] * v;
          }
        }
      }
      double* op = out.px(y, x);
      for (int64_t o = 0; o < O; ++o) op[o] = std::max(acc[static_cast<size_t>(o)], 0.0);
    }
  });
  return out;
}

Map pool2(const Map& in) {
  Map out(in.h / 2, in.w / 2, in.c);
  for (int64_t y = 0; y < out.h; ++y)
    for (int64_t x = 0; x < out.w; ++x)
      for (int64_t c = 0; c < in.c; ++c)
        out.px(y, x)[c] = std::max(std::max(in.px(2 * y, 2 * x)[c], in.px(2 * y, 2 * x + 1)[c]),
                                   std::max(in.px(2 * y + 1, 2 * x)[c], in.px(2 * y + 1, 2 * x + 1)[c]));
  return out;
}

Map up2(const Map& in) {
  Map out(in.h * 2, in.w * 2, in.c);
  for (int64_t y = 0; y < out.h; ++y)
    for (int64_t x = 0; x < out.w; ++x)
      for (int64_t c = 0; c < in.c; ++c) out.px(y, x)[c] = in.px(y / 2, x / 2)[c];
  return out;
}

// Channel concatenation, a's channels first.
Map cat(const Map& a, const Map& b) {
  if (a.h != b.h || a.w != b.w) throw std::invalid_argument("naive_oidn: concatenating maps of different sizes");
  Map out(a.h, a.w, a.c + b.c);
  for (int64_t y = 0; y < a.h; ++y)
    for (int64_t x = 0; x < a.w; ++x) {
      for (int64_t c = 0; c < a.c; ++c) out.px(y, x)[c] = a.px(y, x)[c];
      for (int64_t c = 0; c < b.c; ++c) out.px(y, x)[a.c + c] = b.px(y, x)[c];
    }
  return out;
}

Map unet(const nn::TzaFile& f, const Map& in) {
  const bool large = f.tensors.count("enc_conv1b.weight") > 0;
  Map x, p1, p2, p3, p4;
  if (large) {
    x = conv_relu(f, "enc_conv1a", in);
    x = conv_relu(f, "enc_conv1b", x);
    p1 = pool2(x);
    x = conv_relu(f, "enc_conv2a", p1);
    x = conv_relu(f, "enc_conv2b", x);
    p2 = pool2(x);
    x = conv_relu(f, "enc_conv3a", p2);
    x = conv_relu(f, "enc_conv3b", x);
    p3 = pool2(x);
    x = conv_relu(f, "enc_conv4a", p3);
    x = conv_relu(f, "enc_conv4b", x);
    p4 = pool2(x);
  } else {
    x = conv_relu(f, "enc_conv0", in);
    x = conv_relu(f, "enc_conv1", x);
    p1 = pool2(x);
    x = conv_relu(f, "enc_conv2", p1);
    p2 = pool2(x);
    x = conv_relu(f, "enc_conv3", p2);
    p3 = pool2(x);
    x = conv_relu(f, "enc_conv4", p3);
    p4 = pool2(x);
  }
  x = conv_relu(f, "enc_conv5a", p4);
  x = conv_relu(f, "enc_conv5b", x);
  x = conv_relu(f, "dec_conv4a", cat(up2(x), p3));
  x = conv_relu(f, "dec_conv4b", x);
  x = conv_relu(f, "dec_conv3a", cat(up2(x), p2));
  x = conv_relu(f, "dec_conv3b", x);
  x = conv_relu(f, "dec_conv2a", cat(up2(x), p1));
  x = conv_relu(f, "dec_conv2b", x);
  x = conv_relu(f, "dec_conv1a", cat(up2(x), in));
  x = conv_relu(f, "dec_conv1b", x);
  return large ? conv_relu(f, "dec_conv1c", x) : conv_relu(f, "dec_conv0", x);
}

// --- transfer functions ---------------------------------------------------------------------------------------

enum class Transfer { Linear, Srgb, Pu };

double srgb_forward(double y) { return y <= 0.0031308 ? 12.92 * y : 1.055 * std::pow(y, 1.0 / 2.4) - 0.055; }
double srgb_inverse(double x) { return x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4); }

const double kPuNormScale = 1.0 / pu_forward(65504.0);

double tf_forward(Transfer t, double y) {
  switch (t) {
    case Transfer::Linear: return y;
    case Transfer::Srgb: return srgb_forward(y);
    case Transfer::Pu: return pu_forward(y) * kPuNormScale;
  }
  return y;
}

double tf_inverse(Transfer t, double x) {
  switch (t) {
    case Transfer::Linear: return x;
    case Transfer::Srgb: return srgb_inverse(x);
    case Transfer::Pu: return pu_inverse(x / kPuNormScale);
  }
  return x;
}

// NaN -> 0, then clamp to [lo, hi].
double sanitize(double v, double lo, double hi) {
  if (std::isnan(v)) v = 0.0;
  return std::clamp(v, lo, hi);
}

void check_same_size(const Image& a, const Image& b, const char* what) {
  if (a.width() != b.width() || a.height() != b.height() || b.channels() < 3)
    throw std::invalid_argument(std::string("naive_oidn: the ") + what + " image must be " +
                                std::to_string(a.width()) + " x " + std::to_string(a.height()) + " x 3");
}

}  // namespace

double pu_forward(double y) {
  constexpr double a = 1.41283765e+03, b = 1.64593172e+00, c = 4.31384981e-01, d = -2.94139609e-03;
  constexpr double e = 1.92653254e-01, f = 6.26026094e-03, g = 9.98620152e-01;
  constexpr double y0 = 1.57945760e-06, y1 = 3.22087631e-02;
  if (y <= y0) return a * y;
  if (y <= y1) return b * std::pow(y, c) + d;
  return e * std::log(y + f) + g;
}

double pu_inverse(double x) {
  constexpr double a = 1.41283765e+03, b = 1.64593172e+00, c = 4.31384981e-01, d = -2.94139609e-03;
  constexpr double e = 1.92653254e-01, f = 6.26026094e-03, g = 9.98620152e-01;
  constexpr double x0 = 2.23151711e-03, x1 = 3.70974749e-01;
  if (x <= x0) return x / a;
  if (x <= x1) return std::pow((x - d) / b, 1.0 / c);
  return std::exp((x - g) / e) - f;
}

double oidn_autoexposure(const Image& color) {
  const int64_t H = color.height(), W = color.width();
  if (H <= 0 || W <= 0 || color.channels() < 3) return 1.0;
  const int64_t nbh = (H + 15) / 16, nbw = (W + 15) / 16;
  double log_sum = 0.0;
  int64_t count = 0;
  for (int64_t i = 0; i < nbh; ++i) {
    const int64_t y0 = i * H / nbh, y1 = (i + 1) * H / nbh;
    for (int64_t j = 0; j < nbw; ++j) {
      const int64_t x0 = j * W / nbw, x1 = (j + 1) * W / nbw;
      double sum = 0.0;
      for (int64_t y = y0; y < y1; ++y)
        for (int64_t x = x0; x < x1; ++x) {
          const double r = sanitize(color.at(x, y, 0), 0.0, FLT_MAX);
          const double g = sanitize(color.at(x, y, 1), 0.0, FLT_MAX);
          const double b = sanitize(color.at(x, y, 2), 0.0, FLT_MAX);
          sum += 0.212671 * r + 0.715160 * g + 0.072169 * b;
        }
      const double L = sum / static_cast<double>((y1 - y0) * (x1 - x0));
      if (L > 1e-8) {
        log_sum += std::log2(L);
        ++count;
      }
    }
  }
  return count > 0 ? 0.18 / std::exp2(log_sum / static_cast<double>(count)) : 1.0;
}

Image naive_oidn_filter(const nn::TzaFile& weights, const Image& color, const Image* albedo, const Image* normal,
                        bool hdr, double input_scale) {
  return naive_oidn_filter(weights, color.empty() ? nullptr : &color, albedo, normal, hdr, input_scale);
}

Image naive_oidn_filter(const nn::TzaFile& weights, const Image* color, const Image* albedo, const Image* normal,
                        bool hdr, double input_scale) {
  // Which images, and which transfer function.
  const Image* main = color ? color : albedo ? albedo : normal;
  if (!main) throw std::invalid_argument("naive_oidn: no input image");
  if (main->channels() < 3) throw std::invalid_argument("naive_oidn: the input images need 3 channels");
  if (albedo) check_same_size(*main, *albedo, "albedo");
  if (normal) check_same_size(*main, *normal, "normal");
  if (!color && albedo && normal)
    throw std::invalid_argument("naive_oidn: without colour, filter either the albedo or the normal, not both");
  if (!color && hdr) throw std::invalid_argument("naive_oidn: filtering an albedo or normal alone needs hdr = false");
  const bool snorm = !color && normal;
  const Transfer tf = color ? (hdr ? Transfer::Pu : Transfer::Srgb) : albedo ? Transfer::Srgb : Transfer::Linear;
  if (std::isnan(input_scale)) input_scale = (hdr && color) ? oidn_autoexposure(*color) : 1.0;
  const double output_scale = input_scale != 0.0 ? 1.0 / input_scale : 0.0;

  // Input tensor: colour, albedo, normal (those given), padded with zeros to multiples of 16 at the bottom/right.
  const int64_t W = main->width(), H = main->height();
  const int64_t Hp = (H + 15) / 16 * 16, Wp = (W + 15) / 16 * 16;
  const int64_t C = (color ? 3 : 0) + (albedo ? 3 : 0) + (normal ? 3 : 0);
  Map in(Hp, Wp, C);
  for (int64_t y = 0; y < H; ++y)
    for (int64_t x = 0; x < W; ++x) {
      double* p = in.px(y, x);
      int64_t c0 = 0;
      if (color) {
        for (int c = 0; c < 3; ++c) {
          double v = sanitize(color->at(x, y, c) * input_scale, snorm ? -1.0 : 0.0, hdr ? FLT_MAX : 1.0);
          if (snorm) v = v * 0.5 + 0.5;
          p[c0 + c] = tf_forward(tf, v);
        }
        c0 += 3;
      }
      if (albedo) {
        for (int c = 0; c < 3; ++c) {
          const double a = color ? albedo->at(x, y, c) : albedo->at(x, y, c) * input_scale;
          double v = sanitize(a, 0.0, 1.0);
          if (!color) v = tf_forward(tf, v);
          p[c0 + c] = v;
        }
        c0 += 3;
      }
      if (normal) {
        for (int c = 0; c < 3; ++c) {
          const double n = color ? normal->at(x, y, c) : normal->at(x, y, c) * input_scale;
          p[c0 + c] = sanitize(n, -1.0, 1.0) * 0.5 + 0.5;
        }
      }
    }

  const Map out = unet(weights, in);
  if (out.c < 3 || out.h != Hp || out.w != Wp)
    throw std::invalid_argument("naive_oidn: the network's output is not " + std::to_string(Wp) + " x " +
                                std::to_string(Hp) + " x 3");

  Image result(W, H, 3);
  for (int64_t y = 0; y < H; ++y)
    for (int64_t x = 0; x < W; ++x)
      for (int c = 0; c < 3; ++c) {
        double v = sanitize(out.px(y, x)[c], 0.0, FLT_MAX);
        v = tf_inverse(tf, v);
        if (snorm) v = std::max(v * 2.0 - 1.0, -1.0);
        if (!hdr) v = std::min(v, 1.0);
        result.at(x, y, c) = static_cast<float>(v * output_scale);
      }
  return result;
}

}  // namespace residue::testing
