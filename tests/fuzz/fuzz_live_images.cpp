// libFuzzer harness: the viewer's streamed images as a state machine (several clients, valid and corrupted
// packets, images created, updated, closed and shown). See fuzz_targets.h.
#include "tests/fuzz/fuzz_targets.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  residue::fuzz::live_images_one(data, size);
  return 0;
}
