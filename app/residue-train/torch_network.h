// The paper's network (and its multi-scale variant) as a libtorch module, for training. Module and parameter names are exactly the model
// file's tensor names (core/nn/model_file.h), so the state dict exports as is.
#pragma once

#include <filesystem>
#include <functional>
#include <map>
#include <string>

#include <torch/torch.h>

#include "core/nn/network.h"
#include "core/nn/safetensors.h"

namespace residue::train {

struct ResBlockImpl : torch::nn::Module {
  ResBlockImpl(int width, int dilation);
  torch::Tensor forward(const torch::Tensor& x);
  torch::nn::Conv2d conv1{nullptr}, conv2{nullptr};
  torch::nn::BatchNorm2d bn1{nullptr}, bn2{nullptr};
  torch::nn::PReLU prelu{nullptr};
};
TORCH_MODULE(ResBlock);

struct HeadImpl : torch::nn::Module {
  HeadImpl(int in, int width);
  torch::nn::Conv2d conv{nullptr};
  torch::nn::PReLU prelu{nullptr};
};
TORCH_MODULE(Head);

struct TailImpl : torch::nn::Module {
  explicit TailImpl(int width);
  torch::nn::Conv2d conv{nullptr};
  torch::nn::BatchNorm2d bn{nullptr};
};
TORCH_MODULE(Tail);

struct OutImpl : torch::nn::Module {
  explicit OutImpl(int width);
  torch::nn::Conv2d conv{nullptr};
};
TORCH_MODULE(Out);

// conv (no bias) -> BN -> PReLU: the multi-scale network's down and up steps.
struct ConvBnPReluImpl : torch::nn::Module {
  ConvBnPReluImpl(int in, int out);
  torch::Tensor forward(const torch::Tensor& x);
  torch::nn::Conv2d conv{nullptr};
  torch::nn::BatchNorm2d bn{nullptr};
  torch::nn::PReLU prelu{nullptr};
};
TORCH_MODULE(ConvBnPRelu);

// One level of the multi-scale network (core/nn/network.h): ResBlocks down, the step to the level below, the
// step back up (on the concatenation with `enc`'s output), ResBlocks up. The bottom level has `enc` only.
struct ScaleLevelImpl : torch::nn::Module {
  ScaleLevelImpl(const nn::Architecture& arch, int level);
  torch::nn::ModuleList enc{nullptr}, dec{nullptr};
  ConvBnPRelu down{nullptr}, up{nullptr};
};
TORCH_MODULE(ScaleLevel);

struct ResidueNetImpl : torch::nn::Module {
  explicit ResidueNetImpl(const nn::Architecture& arch);
  // x: N x C_in x H x W feature planes -> N x 3 x H x W (log-compressed colour).
  torch::Tensor forward(const torch::Tensor& x);

  nn::Architecture arch;
  Head head{nullptr};
  torch::nn::ModuleList blocks{nullptr};  // the flat network
  torch::nn::ModuleList levels{nullptr};  // the multi-scale network
  Tail tail{nullptr};
  Out out{nullptr};
};
TORCH_MODULE(ResidueNet);

// He initialisation (for PReLU), zero biases, BN gamma 1 / beta 0; PReLU slopes 0.25.
void initialise(ResidueNet& net);

// Warm start from a trained model file (`source`, read from `path`) of the same blocks, width and dilations,
// typically to fine-tune a variant for another feature set instead of training it from scratch. Every tensor
// is copied; the head's input planes are matched by name (feature_planes): planes the source lacks get zero
// weights and planes only the source had are dropped, so the new network starts out computing exactly what the
// source computes with those planes set to zero. Throws Error(Input) naming the file and the tensor on a mismatch.
void initialise_from(ResidueNet& net, const nn::SafetensorsFile& source, const std::filesystem::path& path);

// Warm start of a multi-scale network one level deeper than `source` (same features, the same blocks and widths
// at the source's levels): every source tensor is copied, and the parts the new bottom level adds start as the
// identity on the source's path, so the grown network computes exactly what the source computes. The old bottom's
// `up` step passes its skip through (an identity centre tap on the skip channels, zero on the upsampled ones; BN
// and PReLU as identities) and its new decoder blocks add zero (their second BN's gamma and beta at 0); the new
// `down` step and bottom blocks keep He initialisation, and their BN statistics (with those of the new decoder
// blocks) are measured over `bn_batches` batches from `next_batch`. Training then learns what the coarser level
// adds (issue 16: our error against OIDN's in interiors is low-frequency). Throws Error(Input) naming the file.
void grow_from(ResidueNet& net, const nn::SafetensorsFile& source, const std::filesystem::path& path,
               const std::function<torch::Tensor()>& next_batch, int bn_batches);

// Warm start of a wider network: the same architecture as `source` with each level (or the flat network) at least
// as wide. Every source tensor is copied into the leading channels of its counterpart; the weights from the new
// channels into the old ones start at zero, so the widened network computes exactly what the source computes, and
// everything into the new channels keeps He initialisation. The new channels' BN statistics are measured over
// `bn_batches` batches from `next_batch` (the old channels keep the source's). Issue 16: the full-resolution level,
// 24 channels against OIDN's 32, is the capacity a noisy wall is denoised with. Throws Error(Input) naming the file.
void widen_from(ResidueNet& net, const nn::SafetensorsFile& source, const std::filesystem::path& path,
                const std::function<torch::Tensor()>& next_batch, int bn_batches);

// "Precise BN": replaces every BatchNorm's running statistics (an exponential average of the last few dozen
// batches, which drifts with the weights and with one unusual batch) by their plain average over `batches`
// batches drawn by `next_batch`, in fp32 with the current weights. Inference uses only these statistics.
void recalibrate_batch_norm(ResidueNet& net, const std::function<torch::Tensor()>& next_batch, int batches);

// Puts every BatchNorm in inference mode (its running statistics, no updates) while the rest trains: the
// network is then fine-tuned with the normalisation it will be run with. Call after net->train().
void freeze_batch_norm(ResidueNet& net);

// Stores every convolution's weights channels-last (NHWC), the layout oneDNN computes in; inputs must be given
// channels-last too (to_channels_last). Each convolution then skips two reorders forward and three backward: 1.19x
// a training step (docs/research/MODELS_HISTORY.md, "Training speed"). Layout only: values, outputs and the exported file are unchanged.
void use_channels_last(ResidueNet& net);
torch::Tensor to_channels_last(const torch::Tensor& batch);

// The state dict as a model file (F32 tensors; BN as trained, folded by core on load) with metadata.
nn::SafetensorsFile export_model(ResidueNet& net, std::map<std::string, std::string> metadata);

}  // namespace residue::train
