// Little-endian integers from bytes, whatever the machine's order (file headers, network packets).
#pragma once

#include <cstddef>
#include <cstdint>

namespace residue {

template <typename T>
T load_little_endian(const uint8_t* p) {
  T v = 0;
  for (size_t i = 0; i < sizeof(T); ++i) v |= static_cast<T>(static_cast<T>(p[i]) << (8 * i));
  return v;
}

inline uint32_t load_le32(const uint8_t* p) { return load_little_endian<uint32_t>(p); }

}  // namespace residue
