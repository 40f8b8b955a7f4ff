// A tev IPC client's packet writer, for tests: little-endian fields appended in order, the length filled in at
// the end (the layout of tev's own Python client). Written here, independently of core/ipc/tev_protocol.cpp,
// so that the decoder is checked against a second reading of the protocol.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace residue::testing {

class TevPacket {
 public:
  explicit TevPacket(uint8_t type) : bytes_(4, 0) { bytes_.push_back(type); }
  TevPacket& u8(uint8_t v) {
    bytes_.push_back(v);
    return *this;
  }
  TevPacket& i32(int32_t v) { return raw(&v, 4); }
  TevPacket& i64(int64_t v) { return raw(&v, 8); }
  TevPacket& f32(float v) { return raw(&v, 4); }
  TevPacket& str(const std::string& s) {
    bytes_.insert(bytes_.end(), s.begin(), s.end());
    return u8(0);
  }
  // The finished packet, its length field filled in (or set to `length`, to lie about it).
  std::vector<uint8_t> done(int64_t length = -1) const {
    std::vector<uint8_t> b = bytes_;
    const uint32_t n = length < 0 ? static_cast<uint32_t>(b.size()) : static_cast<uint32_t>(length);
    for (int i = 0; i < 4; ++i) b[static_cast<size_t>(i)] = static_cast<uint8_t>(n >> (8 * i));
    return b;
  }

 private:
  TevPacket& raw(const void* p, size_t n) {  // the tests run on little-endian machines (x86-64) only
    const auto* c = static_cast<const uint8_t*>(p);
    bytes_.insert(bytes_.end(), c, c + n);
    return *this;
  }
  std::vector<uint8_t> bytes_;
};

}  // namespace residue::testing
