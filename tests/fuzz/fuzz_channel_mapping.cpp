// libFuzzer harness: the --map flag and the JSON channel mapping parsers. See fuzz_targets.h.
#include "tests/fuzz/fuzz_targets.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  residue::fuzz::channel_mapping_one(data, size);
  return 0;
}
