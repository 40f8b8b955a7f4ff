#include "core/util/openmp_env.h"

#include <cstdlib>
#include <vector>

#if defined(__linux__)
#include <unistd.h>
#endif

namespace residue {
namespace {

#if defined(__linux__) && defined(RESIDUE_HAVE_ONEDNN)  // without oneDNN nothing here runs on OpenMP
bool g_set_before_libraries = false;

// Runs before every shared library's initialiser (an executable's .preinit_array); libc is relocated and
// usable by then. overwrite = 0: a user's own OMP_WAIT_POLICY wins.
void set_passive_before_libraries(int, char**, char**) {
  g_set_before_libraries = setenv("OMP_WAIT_POLICY", "passive", 0) == 0;
}

[[gnu::section(".preinit_array"), gnu::used]] void (*const g_preinit)(int, char**, char**) =
    &set_passive_before_libraries;
#endif

}  // namespace

void ensure_passive_openmp(int argc, char** argv) {
#if defined(__linux__) && defined(RESIDUE_HAVE_ONEDNN)
  if (g_set_before_libraries || std::getenv("OMP_WAIT_POLICY") != nullptr || argc < 1 || argv == nullptr) return;
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
