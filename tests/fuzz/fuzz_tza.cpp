// libFuzzer harness: OIDN's .tza archives and the UNet built from them. See fuzz_targets.h.
#include "tests/fuzz/fuzz_targets.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  residue::fuzz::tza_one(data, size);
  return 0;
}
