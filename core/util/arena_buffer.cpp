#include "core/util/arena_buffer.h"

#include <algorithm>
#include <cstdlib>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace residue {

namespace {
constexpr size_t kHugePage = size_t{2} << 20;
}

ArenaBuffer::~ArenaBuffer() { std::free(data_); }

void ArenaBuffer::grow(size_t bytes) {
  if (bytes <= capacity_ && data_) return;
  std::free(data_);
  data_ = nullptr;
  capacity_ = 0;
  const size_t align = bytes >= kHugePage ? kHugePage : 64;
  const size_t size = (std::max<size_t>(bytes, 64) + align - 1) / align * align;
  data_ = std::aligned_alloc(align, size);
  if (!data_) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (align == kHugePage) madvise(data_, size, MADV_HUGEPAGE);  // a hint: ignored where THP is off
#endif
  capacity_ = size;
}

}  // namespace residue
