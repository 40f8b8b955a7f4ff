// The portable fp32 backend: each 3x3 conv is an im2col + GEMM (Eigen) over strips of rows, the strips run in
// parallel on oneTBB. Bias, PReLU and the residual add are applied while the strip is still in cache.
#include <algorithm>
#include <cstring>

#include <Eigen/Core>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "core/nn/backend.h"

namespace residue::nn {
namespace {

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// A conv's weights as the GEMM wants them: (9 * in) x out, row (ky * 3 + kx) * in + i.
struct PackedConv {
  int in = 0, out = 0;
  RowMatrix weights;
  std::vector<float> bias;
  std::vector<float> prelu;  // empty: no activation
};

PackedConv pack(const Conv3x3& c, const std::vector<float>& prelu = {}) {
  PackedConv p;
  p.in = c.in;
  p.out = c.out;
  p.weights.resize(9 * c.in, c.out);
  for (int o = 0; o < c.out; ++o)
    for (int i = 0; i < c.in; ++i)
      for (int ky = 0; ky < 3; ++ky)
        for (int kx = 0; kx < 3; ++kx) p.weights((ky * 3 + kx) * c.in + i, o) = c.w(o, i, ky, kx);
  p.bias = c.bias;
  p.prelu = prelu;
  return p;
}

constexpr int64_t kStripPixels = 2048;  // im2col rows per GEMM: ~9 MB of patches at W = 128

class EigenBackend final : public Backend {
 public:
  explicit EigenBackend(const Network& n) : arch_(n.arch) {
    head_ = pack(n.head, n.head_prelu);
    for (const auto& b : n.blocks) {
      blocks_.push_back(pack(b.conv1, b.prelu));
      blocks_.push_back(pack(b.conv2));
    }
    tail_ = pack(n.tail);
    out_ = pack(n.out);
  }

  std::string description() const override { return "eigen fp32"; }

  size_t scratch_bytes(int64_t width, int64_t height) const override {
    // Three activation buffers (head output, block state, temporary) + one im2col strip per thread.
    const size_t act = static_cast<size_t>(width * height * arch_.width) * sizeof(float);
    return 3 * act + 2 * static_cast<size_t>(kStripPixels * 9 * arch_.width) * sizeof(float);
  }

  void run(const Image& input, Image& output) override {
    const int64_t h = input.height(), w = input.width();
    const size_t n = static_cast<size_t>(h * w * arch_.width);
    head_out_.resize(n);
    state_.resize(n);
    temp_.resize(n);
    conv(input.data(), h, w, head_, head_out_.data(), nullptr);
    std::memcpy(state_.data(), head_out_.data(), n * sizeof(float));
    for (size_t b = 0; b < blocks_.size(); b += 2) {
      conv(state_.data(), h, w, blocks_[b], temp_.data(), nullptr);
      conv(temp_.data(), h, w, blocks_[b + 1], state_.data(), state_.data());  // in place: + identity
    }
    conv(state_.data(), h, w, tail_, temp_.data(), head_out_.data());
    output = Image(w, h, 3);
    conv(temp_.data(), h, w, out_, output.data(), nullptr);
  }

 private:
  // out = act(conv(in) + bias) (+ add). `out` may alias `add` (the residual), never `in`.
  void conv(const float* in, int64_t h, int64_t w, const PackedConv& c, float* out, const float* add) {
    const int64_t rows_per_strip = std::max<int64_t>(1, kStripPixels / std::max<int64_t>(w, 1));
    const int64_t strips = (h + rows_per_strip - 1) / rows_per_strip;
    tbb::parallel_for(int64_t{0}, strips, [&](int64_t s) {
      const int64_t y0 = s * rows_per_strip, y1 = std::min(h, y0 + rows_per_strip);
      const int64_t pixels = (y1 - y0) * w;
      std::vector<float>& cols = im2col_.local();
      cols.resize(static_cast<size_t>(pixels * 9 * c.in));
      // Patches: for each pixel, the 3x3 neighbourhood's channels, zeros outside the tile.
      for (int64_t y = y0; y < y1; ++y)
        for (int64_t x = 0; x < w; ++x) {
          float* dst = cols.data() + ((y - y0) * w + x) * 9 * c.in;
          for (int ky = 0; ky < 3; ++ky)
            for (int kx = 0; kx < 3; ++kx, dst += c.in) {
              const int64_t sy = y + ky - 1, sx = x + kx - 1;
              if (sy < 0 || sy >= h || sx < 0 || sx >= w) std::fill(dst, dst + c.in, 0.0f);
              else std::memcpy(dst, in + (sy * w + sx) * c.in, static_cast<size_t>(c.in) * sizeof(float));
            }
        }
      Eigen::Map<const RowMatrix> patches(cols.data(), pixels, 9 * c.in);
      Eigen::Map<RowMatrix> result(out + y0 * w * c.out, pixels, c.out);
      if (add) {
        Eigen::Map<const RowMatrix> residual(add + y0 * w * c.out, pixels, c.out);
        result = (patches * c.weights).eval() + residual;  // eval(): `out` may alias `add`
      } else {
        result.noalias() = patches * c.weights;
      }
      for (int64_t p = 0; p < pixels; ++p) {
        float* v = out + (y0 * w + p) * c.out;
        for (int o = 0; o < c.out; ++o) {
          float x = v[o] + c.bias[static_cast<size_t>(o)];
          if (!c.prelu.empty() && x < 0) x *= c.prelu[static_cast<size_t>(o)];
          v[o] = x;
        }
      }
    });
  }

  Architecture arch_;
  PackedConv head_, tail_, out_;
  std::vector<PackedConv> blocks_;
  std::vector<float> head_out_, state_, temp_;
  tbb::enumerable_thread_specific<std::vector<float>> im2col_;
};

}  // namespace

std::unique_ptr<Backend> make_eigen_backend(const Network& network) {
  return std::make_unique<EigenBackend>(network);
}

}  // namespace residue::nn
