#include "core/nn/backend.h"

#include "core/util/error.h"

namespace residue::nn {

#ifdef RESIDUE_HAVE_ONEDNN
std::unique_ptr<Backend> make_onednn_backend(const Graph& graph, Precision precision);
bool onednn_has_native_bf16();
#endif

const char* to_string(Precision p) {
  switch (p) {
    case Precision::BF16: return "bf16";
    case Precision::INT8: return "int8";
    case Precision::FP32: break;
  }
  return "fp32";
}

std::vector<std::string> precision_names() {
  return {to_string(Precision::FP32), to_string(Precision::BF16), to_string(Precision::INT8)};
}

Precision parse_precision(std::string_view name) {
  for (Precision p : {Precision::FP32, Precision::BF16, Precision::INT8})
    if (name == to_string(p)) return p;
  throw Error(ErrorKind::Usage, "precision '" + std::string(name) + "' is not one of fp32, bf16, int8");
}

void Backend::record_ranges(std::vector<float>*, double) {
  throw Error(ErrorKind::Usage, "the " + description() + " backend cannot record value ranges; calibrate with onednn fp32");
}

std::vector<std::string> available_backends() {
  std::vector<std::string> names = {"eigen"};
#ifdef RESIDUE_HAVE_ONEDNN
  names.push_back("onednn");
#endif
  return names;
}

bool bf16_available() {
#ifdef RESIDUE_HAVE_ONEDNN
  return onednn_has_native_bf16();
#else
  return false;
#endif
}

std::string default_backend(Precision precision) {
  // fp32: eigen with its AVX-512 kernel. At the automatic tile (1024) it matches onednn on the flat models and is
  // 5-12 % faster on OIDN's UNet, whose halo it skips (docs/PERFORMANCE.md, "The fp32 default and the arena's first
  // touch"). Without AVX-512 eigen's portable path is 1.5-3.5x slower than onednn's AVX2 kernels on all but the
  // narrowest models ("The portable path"), so onednn where it is built. bf16 and int8 are onednn's alone.
  if (precision != Precision::FP32 || !eigen_runs_direct_kernel()) return available_backends().back();
  return "eigen";
}

std::unique_ptr<Backend> make_backend(const std::string& name, const Network& network, const BackendOptions& options) {
  return make_backend(name, to_graph(network), options);
}

std::unique_ptr<Backend> make_backend(const std::string& name, const Graph& graph, const BackendOptions& options) {
  if (name == "eigen") {
    if (options.precision != Precision::FP32)
      throw Error(ErrorKind::Usage, std::string("the eigen backend computes in fp32 only; use --backend onednn for ") +
                                        to_string(options.precision));
    return make_eigen_backend(graph);
  }
#ifdef RESIDUE_HAVE_ONEDNN
  if (name == "onednn") return make_onednn_backend(graph, options.precision);
#endif
  std::string list;
  for (const auto& n : available_backends()) list += (list.empty() ? "" : ", ") + n;
  throw Error(ErrorKind::Usage, "unknown or unavailable backend \"" + name + "\"; available: " + list);
}

}  // namespace residue::nn
