#include "core/util/arena_buffer.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <new>

#include <tbb/parallel_for.h>

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
  // First touch here, on every thread of the caller's arena: the kernel zeroes each fresh page on the thread that
  // faults it, and the first writer is otherwise often one thread (a value's zero border, an input copy), which
  // left a cold 1024 tile of OIDN's UNet at 1.7 of 2 cores (perf: 1.1 s of single-threaded page zeroing).
  const size_t chunks = (size + kHugePage - 1) / kHugePage;
  tbb::parallel_for(size_t{0}, chunks, [&](size_t i) {
    const size_t begin = i * kHugePage;
    std::memset(static_cast<char*>(data_) + begin, 0, std::min(kHugePage, size - begin));
  });
}

}  // namespace residue
