// A large, aligned, reusable block of memory for a network's activations (the arena of core/nn/arena.h).
//
// Why not std::vector: a fresh 100 MB-1 GB arena is mostly page faults when first written (4 KiB pages: ~250 k
// faults for 1 GB, measured at ~0.4 s per 128 MB on these VMs), so buffers of 2 MiB or more are aligned to 2 MiB
// and marked for transparent huge pages (madvise; Debian's default THP mode), which cuts the faults 512-fold.
// A fresh buffer is written once in parallel (zeros) so that its page faults are shared by the threads; contents
// are otherwise unspecified: grow() keeps nothing.
#pragma once

#include <cstddef>

namespace residue {

class ArenaBuffer {
 public:
  ArenaBuffer() = default;
  ~ArenaBuffer();
  ArenaBuffer(const ArenaBuffer&) = delete;
  ArenaBuffer& operator=(const ArenaBuffer&) = delete;

  // Makes room for `bytes` (64-byte aligned at least); reallocates only when it grows.
  void grow(size_t bytes);
  void* data() const { return data_; }
  size_t capacity() const { return capacity_; }

 private:
  void* data_ = nullptr;
  size_t capacity_ = 0;
};

}  // namespace residue
