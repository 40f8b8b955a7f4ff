// libFuzzer harness: tev's IPC protocol, as the viewer's server receives it. See fuzz_targets.h.
#include "tests/fuzz/fuzz_targets.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  residue::fuzz::tev_ipc_one(data, size);
  return 0;
}
