// libFuzzer harness: the EXR/AOV loader (channel naming, data windows, multipart). See fuzz_targets.h.
#include "tests/fuzz/fuzz_targets.h"

// One thread for OpenImageIO and OpenEXR: the fuzzer runs one input at a time, and threads only add noise.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  OIIO::attribute("threads", 1);
  OIIO::attribute("exr_threads", 1);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  residue::fuzz::exr_loader_one(data, size);
  return 0;
}
