// One 3x3 convolution, 256 x 256, C to C channels, fp32 / bf16 / int8 (s8 source, s8 weights, s8 output) through
// oneDNN, timed in one run: what docs/PERFORMANCE.md "int8 on AVX512-VNNI" expects of int8 before the network.
// Build and run: g++ -O2 -std=c++17 tools/research/int8/conv_microbench.cpp -o /tmp/conv_microbench -ldnnl &&
//               OMP_NUM_THREADS=2 /tmp/conv_microbench
#include <dnnl.hpp>
#include <chrono>
#include <cstdio>
#include <vector>
#include <cstring>
#include <unordered_map>
using namespace dnnl;
using dt = memory::data_type; using tag = memory::format_tag;
double run(dt src_t, dt wei_t, dt dst_t, int C, int H, int W, bool int8) {
  engine eng(engine::kind::cpu, 0); stream s(eng);
  memory::desc src({1, C, H, W}, src_t, tag::any), wei({C, C, 3, 3}, wei_t, tag::any),
      bias({C}, dt::f32, tag::a), dst({1, C, H, W}, dst_t, tag::any);
  convolution_forward::desc d(prop_kind::forward_inference, algorithm::convolution_direct, src, wei, bias, dst,
                              {1, 1}, {1, 1}, {1, 1});
  primitive_attr attr;
  post_ops ops; ops.append_eltwise(1.f, algorithm::eltwise_relu, 0.1f, 0.f);
  if (int8) { attr.set_output_scales(2, std::vector<float>(C, 0.01f)); }
  attr.set_post_ops(ops);
  convolution_forward::primitive_desc pd(d, attr, eng);
  memory ms(pd.src_desc(), eng), mw(pd.weights_desc(), eng), mb(pd.bias_desc(), eng), md(pd.dst_desc(), eng);
  memset(ms.get_data_handle(), 1, pd.src_desc().get_size());
  memset(mw.get_data_handle(), 1, pd.weights_desc().get_size());
  memset(mb.get_data_handle(), 0, pd.bias_desc().get_size());
  convolution_forward conv(pd);
  std::unordered_map<int, memory> args{{DNNL_ARG_SRC, ms}, {DNNL_ARG_WEIGHTS, mw}, {DNNL_ARG_BIAS, mb}, {DNNL_ARG_DST, md}};
  for (int i = 0; i < 3; ++i) conv.execute(s, args);
  s.wait();
  int n = 20; auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < n; ++i) conv.execute(s, args);
  s.wait();
  double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / n;
  const char* impl; dnnl_primitive_desc_query(pd.get(), dnnl_query_impl_info_str, 0, &impl);
  double gflops = 2.0 * C * C * 9 * H * W / t / 1e9;
  std::printf("C=%3d %dx%d %-6s %-40s %8.3f ms %7.1f GOP/s\n", C, H, W, int8 ? "int8" : (src_t == dt::bf16 ? "bf16" : "f32"), impl, t * 1e3, gflops);
  return t;
}
int main() {
  for (int C : {24, 32, 40, 56, 64, 80, 96}) {
    double f = run(dt::f32, dt::f32, dt::f32, C, 256, 256, false);
    double b = run(dt::bf16, dt::bf16, dt::bf16, C, 256, 256, false);
    double i = run(dt::u8, dt::s8, dt::u8, C, 256, 256, true);
    double i2 = run(dt::s8, dt::s8, dt::s8, C, 256, 256, true);
    std::printf("  ratio int8(u8)/bf16 %.2f  int8(s8)/bf16 %.2f  bf16/f32 %.2f\n", i / b, i2 / b, b / f);
  }
}
