// A training run's checkpoint folder: the network, the optimiser, the step and the training time so far (wall_s:
// summed over resumed runs), each replaced atomically, the step last, so that a kill in between leaves the previous
// checkpoint whole and a restarted run goes on from it.
#pragma once

#include <filesystem>
#include <fstream>

#include <torch/torch.h>

namespace residue::train {

template <class Net>
void save_checkpoint(const std::filesystem::path& dir, Net& net, torch::optim::Optimizer& opt, int step, double wall_s = 0) {
  namespace fs = std::filesystem;
  fs::create_directories(dir);
  std::ofstream(dir / "wall_s.tmp") << wall_s;
  fs::rename(dir / "wall_s.tmp", dir / "wall_s");
  torch::save(net, (dir / "model.pt.tmp").string());
  torch::save(opt, (dir / "optim.pt.tmp").string());
  fs::rename(dir / "model.pt.tmp", dir / "model.pt");
  fs::rename(dir / "optim.pt.tmp", dir / "optim.pt");
  std::ofstream(dir / "step.tmp") << step;
  fs::rename(dir / "step.tmp", dir / "step");
}

// The step the checkpoint in `dir` was saved at (its network and optimiser loaded into `net` and `opt`), and its
// training time in `wall_s` when given.
template <class Net>
int load_checkpoint(const std::filesystem::path& dir, Net& net, torch::optim::Optimizer& opt, double* wall_s = nullptr) {
  torch::load(net, (dir / "model.pt").string());
  torch::load(opt, (dir / "optim.pt").string());
  int step = 0;
  std::ifstream(dir / "step") >> step;
  if (wall_s && std::filesystem::exists(dir / "wall_s")) std::ifstream(dir / "wall_s") >> *wall_s;
  return step;
}

}  // namespace residue::train
