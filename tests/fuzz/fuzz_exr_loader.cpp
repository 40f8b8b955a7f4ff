// libFuzzer harness: the EXR/AOV loader (channel naming, data windows, multipart). See fuzz_targets.h.
#include "tests/fuzz/fuzz_targets.h"

// One thread for OpenImageIO and OpenEXR: the fuzzer runs one input at a time, and threads only add noise.
// try_all_readers 0: a corrupt .exr is read by the OpenEXR reader only. By default OpenImageIO then tries every
// other format reader on it (DICOM, FFmpeg, ...), which made the first 10-minute run spend its time in those
// readers (5 inputs a second) and end in an out-of-memory at 2.1 GB of RSS inside them.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  OIIO::attribute("threads", 1);
  OIIO::attribute("exr_threads", 1);
  OIIO::attribute("try_all_readers", 0);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  residue::fuzz::exr_loader_one(data, size);
  return 0;
}
