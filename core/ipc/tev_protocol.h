// tev's IPC protocol, decoded: the packets renderers and scripts send to an image viewer over TCP (pbrt-v4,
// Mitsuba, tev's own Python and C++ clients), so that they can stream images into Residue's viewer.
//
// A packet is little-endian: u32 length (of the whole packet, these 4 bytes included), u8 type, then fields;
// strings are UTF-8 ending in a NUL byte, flags one byte. Types:
//   0 open image       flag grab_focus, string "PATH[:CHANNELS]"
//   7 open image v2    flag grab_focus, string path, string channel selector
//   1 reload image     flag grab_focus, string name
//   2 close image      string name
//   4 create image     flag grab_focus, string name, i32 width, i32 height, i32 n, n strings (channel names)
//   3 update image     flag grab_focus, string name, string channel, i32 x, y, width, height, width*height floats
//   5 update image v2  flag grab_focus, string name, i32 n, n strings, i32 x, y, width, height, n planes of floats
//   6 update image v3  as v2, then i64 offset[n], i64 stride[n], floats: channel c of pixel p (row-major in the
//                      width x height region) at offset[c] + p * stride[c]
//   8 vector graphics  recognised and refused (overlays are not drawn)
// No I/O here: the viewer owns the socket; this file turns bytes into packets and refuses bad ones with an Error
// that says which field is wrong, so that a malformed client never takes the viewer down.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <variant>
#include <vector>

namespace residue::ipc {

inline constexpr uint16_t kTevDefaultPort = 14158;

struct OpenImage {
  bool grab_focus = true;
  std::string path;
  std::string channel_selector;  // empty = all channels
};

struct ReloadImage {
  bool grab_focus = true;
  std::string name;
};

struct CloseImage {
  std::string name;
};

struct CreateImage {
  bool grab_focus = true;
  std::string name;
  int32_t width = 0, height = 0;
  std::vector<std::string> channel_names;
};

// A rectangle of pixels for some channels of a created image, each channel as its own row-major plane.
struct UpdateImage {
  bool grab_focus = false;
  std::string name;
  int32_t x = 0, y = 0, width = 0, height = 0;
  std::vector<std::string> channel_names;
  std::vector<std::vector<float>> planes;  // one per channel, width * height values
};

using TevPacket = std::variant<OpenImage, ReloadImage, CloseImage, CreateImage, UpdateImage>;

// Limits that keep a hostile or broken client from making the viewer allocate without bound.
struct TevLimits {
  uint32_t max_packet_bytes = 512u << 20;     // one update packet; tev's clients send 128x128 tiles
  int32_t max_channels = 1024;
  int64_t max_image_values = int64_t{1} << 30;  // width * height * channels of a created image (4 GiB of floats)
};

// Decodes one whole packet (its length field included). Throws Error(Input) naming the packet type and the
// field that is wrong: a length that disagrees with the bytes, an unknown type, a string without its end, a
// negative or too large size, data that does not hold what the header declares.
TevPacket parse_tev_packet(std::span<const uint8_t> packet, const TevLimits& limits = {});

// Splits a TCP byte stream into packets. feed() what arrives, then take next() until it returns nothing. A length
// field below 5 bytes or above the limit is an Error(Input): the stream cannot be resynchronised after it, so the
// connection should be closed.
class TevPacketStream {
 public:
  explicit TevPacketStream(const TevLimits& limits = {}) : limits_(limits) {}
  void feed(std::span<const uint8_t> bytes);
  std::optional<std::vector<uint8_t>> next();
  size_t buffered() const { return buffer_.size() - start_; }

 private:
  TevLimits limits_;
  std::vector<uint8_t> buffer_;
  size_t start_ = 0;  // the first byte not yet returned
};

}  // namespace residue::ipc
