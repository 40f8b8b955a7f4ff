#include "core/denoise/method_registry.h"

#include <deque>
#include <mutex>

#include "core/nn/model_card.h"
#include "core/util/error.h"

namespace residue {
namespace {

std::deque<MethodEntry>& table() {  // a deque: entries stay where they are as others are added
  static std::deque<MethodEntry> entries = {
      {"residue", "Residue's direct residual networks (.safetensors)", true, make_residue_method},
      {"oidn", "Open Image Denoise's networks as OIDN runs them (.tza), for comparison", true, make_oidn_method},
      {"temporal", "Residue's temporal networks: a frame of a shot with its neighbours warped to it", true,
       make_temporal_method},
      {"bilateral", "the cross-bilateral filter guided by the AOVs: the baseline, no model", false, make_bilateral_method},
  };
  return entries;
}

std::mutex& table_mutex() {
  static std::mutex m;
  return m;
}

}  // namespace

void register_method(MethodEntry entry) {
  std::lock_guard lock(table_mutex());
  for (MethodEntry& e : table())
    if (e.family == entry.family) {
      e = std::move(entry);
      return;
    }
  table().push_back(std::move(entry));
}

const MethodEntry* find_method(std::string_view family) {
  std::lock_guard lock(table_mutex());
  for (const MethodEntry& e : table())
    if (e.family == family) return &e;
  return nullptr;
}

std::vector<std::string> method_families() {
  std::lock_guard lock(table_mutex());
  std::vector<std::string> names;
  for (const MethodEntry& e : table()) names.push_back(e.family);
  return names;
}

std::unique_ptr<Method> make_method(std::shared_ptr<const nn::Model> model) {
  if (!model) throw Error(ErrorKind::Usage, "make_method: no model");
  const std::string kind = model->method == nn::Method::Residue && model->network.arch.temporal > 0
                               ? "temporal"
                               : nn::to_string(model->method);
  const MethodEntry* e = find_method(kind);
  if (!e) throw Error(ErrorKind::Usage, "no method runs models of kind " + kind);
  return e->make(std::move(model));
}

std::unique_ptr<Method> make_method(std::string_view family) {
  const MethodEntry* e = find_method(family);
  if (!e || e->needs_model) {
    std::string known;
    for (const std::string& f : method_families())
      if (const MethodEntry* m = find_method(f); m && !m->needs_model) known += (known.empty() ? "" : ", ") + f;
    throw Error(ErrorKind::Usage, "'" + std::string(family) + "' is not a method without a model (those are: " + known + ")");
  }
  return e->make(nullptr);
}

std::unique_ptr<Method> resolve_method(const std::string& name_or_path, FeatureSet available, nn::ModelRegistry& models) {
  if (is_model_free_method(name_or_path)) return make_method(std::string_view(name_or_path));
  return make_method(models.load(name_or_path, available));
}

bool is_model_free_method(std::string_view name) {
  const MethodEntry* e = find_method(name);
  return e && !e->needs_model;
}

}  // namespace residue
