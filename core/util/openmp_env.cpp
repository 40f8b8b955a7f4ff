#include "core/util/openmp_env.h"

#include <cstdlib>
#include <vector>

#if defined(__linux__)
#include <unistd.h>
#endif

namespace residue {

void ensure_passive_openmp(int argc, char** argv) {
#if defined(__linux__) && defined(RESIDUE_HAVE_ONEDNN)  // without oneDNN nothing here runs on OpenMP
  if (std::getenv("OMP_WAIT_POLICY") != nullptr || argc < 1 || argv == nullptr) return;
  if (setenv("OMP_WAIT_POLICY", "passive", 1) != 0) return;
  // The environment variable also stops a second re-execution. argv is copied so that it ends in nullptr.
  std::vector<char*> args(argv, argv + argc);
  args.push_back(nullptr);
  execv("/proc/self/exe", args.data());
  // Only reached when execv failed (no /proc): go on as we are.
#else
  (void)argc;
  (void)argv;
#endif
}

}  // namespace residue
