// Quantisation-aware training's torch graph (app/residue-train/quantised_graph.h) computes what core computes: the
// float network as the fp32 backends do, and the int8 plan's rounding as onednn's int8 run does.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>

#include "core/nn/backend.h"
#include "core/nn/network.h"
#include "quantised_graph.h"
#include "support/test_support.h"

namespace residue {
namespace {

torch::Tensor to_nchw(const Image& x) {
  torch::Tensor t = torch::empty({1, x.channels(), x.height(), x.width()});
  auto a = t.accessor<float, 4>();
  for (int c = 0; c < x.channels(); ++c)
    for (int64_t y = 0; y < x.height(); ++y)
      for (int64_t i = 0; i < x.width(); ++i) a[0][c][y][i] = x.at(i, y, c);
  return t;
}

Image to_image(const torch::Tensor& t) {
  Image out(t.size(3), t.size(2), static_cast<int>(t.size(1)));
  auto a = t.accessor<float, 4>();
  for (int c = 0; c < out.channels(); ++c)
    for (int64_t y = 0; y < out.height(); ++y)
      for (int64_t i = 0; i < out.width(); ++i) out.at(i, y, c) = a[0][c][y][i];
  return out;
}

double rms_difference(const Image& a, const Image& b) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += (a.data()[i] - b.data()[i]) * (a.data()[i] - b.data()[i]);
  return std::sqrt(s / static_cast<double>(a.size()));
}

// Three levels (a pool, an upsample and a concat conv with per-channel PReLU at each), the input skip (kept in
// f32 by the plan), a tail that reads s8 and writes f32: every case of the plan's rounding.
nn::Network test_network() {
  nn::Architecture arch{1, 8, FeatureSet::Full, {}, true, {1, 1, 1}, {8, 12, 16}};
  return nn::random_network(arch, 11);
}

TEST(QuantisedGraph, FloatIsCoresFp32AndRoundedIsCoresInt8) {
  const auto backends = nn::available_backends();
  if (std::find(backends.begin(), backends.end(), "onednn") == backends.end()) GTEST_SKIP() << "no onednn backend";
  const nn::Network net = test_network();
  nn::Graph graph = nn::to_graph(net);
  const Image x = testing::random_image(32, 24, 9, 5, -0.5f, 1.5f);

  Image fp32, int8;
  std::vector<float> ranges(static_cast<size_t>(graph.size()), 0.0f);
  {
    auto b = nn::make_backend("onednn", graph, {nn::Precision::FP32});
    b->record_ranges(&ranges);
    b->run(x, fp32);
  }
  for (int i = 0; i < graph.size(); ++i) graph.set_range(i, ranges[static_cast<size_t>(i)]);
  nn::make_backend("onednn", graph, {nn::Precision::INT8})->run(x, int8);

  train::QuantisedGraph q(graph, ranges);
  torch::NoGradGuard no_grad;
  const Image real = to_image(q->forward(to_nchw(x), false));
  const Image rounded = to_image(q->forward(to_nchw(x), true));
  double scale = 0;
  for (size_t i = 0; i < fp32.size(); ++i) scale = std::max(scale, static_cast<double>(std::abs(fp32.data()[i])));
  EXPECT_LT(rms_difference(real, fp32), 1e-5 * scale);
  // int8 is visibly off fp32 on random weights; the rounded graph explains nearly all of it.
  const double int8_error = rms_difference(int8, fp32);
  EXPECT_GT(int8_error, 1e-3 * scale);
  EXPECT_LT(rms_difference(rounded, int8), 0.1 * int8_error)
      << "int8 off fp32 by " << int8_error << ", the rounded graph off int8 by " << rms_difference(rounded, int8);

  // Rounding chosen per op (the sensitivity study): every op is the int8 plan, none the float network, and each
  // value alone moves the output by less than all of them together.
  const std::vector<bool> every(static_cast<size_t>(q->size()), true), none(every.size(), false);
  EXPECT_TRUE(torch::equal(q->forward(to_nchw(x), every), q->forward(to_nchw(x), true)));
  EXPECT_TRUE(torch::equal(q->forward(to_nchw(x), none), q->forward(to_nchw(x), false)));
  int quantised = 0;
  for (int i = 0; i < q->size(); ++i) {
    if (!q->rounds(i)) continue;
    ++quantised;
    std::vector<bool> alone = none;
    alone[static_cast<size_t>(i)] = true;
    const double moved = rms_difference(to_image(q->forward(to_nchw(x), alone)), real);
    EXPECT_GT(moved, 0.0) << graph.op(i).name;
    EXPECT_LT(moved, rms_difference(rounded, real)) << graph.op(i).name;
  }
  EXPECT_GT(quantised, 5);
}

TEST(QuantisedGraph, RangesAndWeightsLearnAndGoBackIntoTheNetwork) {
  const nn::Network net = test_network();
  const nn::Graph graph = nn::to_graph(net);
  std::vector<float> ranges(static_cast<size_t>(graph.size()), 0.0f);
  train::QuantisedGraph probe(graph, std::vector<float>(ranges.size(), 1.0f));
  const torch::Tensor x = to_nchw(testing::random_image(32, 24, 9, 6, -0.5f, 1.5f));
  {
    torch::NoGradGuard no_grad;
    probe->forward(x, false, &ranges);
  }
  for (float& r : ranges) r *= 0.25f;  // clipping: the ranges' gradients must then say "grow"
  train::QuantisedGraph q(graph, ranges);
  const torch::Tensor target = probe->forward(x, false).detach();
  const torch::Tensor loss = (q->forward(x) - target).abs().mean();
  loss.backward();
  int ranges_with_gradient = 0;
  for (const auto& r : q->range_parameters()) {
    ASSERT_TRUE(r.grad().defined());
    ASSERT_TRUE(std::isfinite(r.grad().item<double>()));
    ranges_with_gradient += r.grad().item<double>() != 0.0;
  }
  EXPECT_GT(ranges_with_gradient, static_cast<int>(q->range_parameters().size()) / 2);
  for (const auto& w : q->weight_parameters()) ASSERT_TRUE(torch::isfinite(w.grad()).all().item<bool>());

  // A step changes the weights; written back, the network's graph is the trained one.
  {
    torch::NoGradGuard no_grad;
    for (auto& w : q->weight_parameters()) w.sub_(1e-2 * w.grad().sign());
  }
  nn::Graph trained = graph;
  q->write_to(trained);
  nn::Network back = net;
  nn::set_weights_from_graph(back, trained);
  const nn::Graph again = nn::to_graph(back);
  ASSERT_EQ(again.size(), trained.size());
  int changed = 0;
  for (int i = 0; i < trained.size(); ++i) {
    EXPECT_EQ(again.op(i).weight, trained.op(i).weight) << trained.op(i).name;
    EXPECT_EQ(again.op(i).bias, trained.op(i).bias) << trained.op(i).name;
    EXPECT_EQ(again.op(i).slopes, trained.op(i).slopes) << trained.op(i).name;
    changed += again.op(i).weight != graph.op(i).weight;
    // The calibration's ranges: every value the plan rounds has one, a pool's or upsample's is its source's.
    if (trained.op(i).kind == nn::OpKind::Pool || trained.op(i).kind == nn::OpKind::Upsample)
      EXPECT_EQ(trained.op(i).range, trained.op(trained.op(i).inputs[0]).range);
  }
  EXPECT_GT(changed, 5);
  EXPECT_GT(trained.op(0).range, 0.0f) << "the input is quantised";
  EXPECT_EQ(trained.op(trained.output()).range, 0.0f) << "the output is kept in f32";
}

}  // namespace
}  // namespace residue
