// libFuzzer harness: the safetensors reader and the Residue model loader. See fuzz_targets.h.
#include "tests/fuzz/fuzz_targets.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  residue::fuzz::safetensors_one(data, size);
  return 0;
}
