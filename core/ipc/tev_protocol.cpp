#include "core/ipc/tev_protocol.h"

#include <algorithm>
#include <cstring>
#include <limits>

#include "core/util/error.h"
#include "core/util/little_endian.h"

namespace residue::ipc {
namespace {

enum class Type : uint8_t {
  OpenImage = 0,
  ReloadImage = 1,
  CloseImage = 2,
  UpdateImage = 3,
  CreateImage = 4,
  UpdateImageV2 = 5,
  UpdateImageV3 = 6,
  OpenImageV2 = 7,
  VectorGraphics = 8,
};

const char* type_name(uint8_t type) {
  switch (static_cast<Type>(type)) {
    case Type::OpenImage: return "open image";
    case Type::ReloadImage: return "reload image";
    case Type::CloseImage: return "close image";
    case Type::UpdateImage: return "update image";
    case Type::CreateImage: return "create image";
    case Type::UpdateImageV2: return "update image v2";
    case Type::UpdateImageV3: return "update image v3";
    case Type::OpenImageV2: return "open image v2";
    case Type::VectorGraphics: return "vector graphics";
  }
  return "unknown";
}

// Reads the fields of one packet in order; every read checks that the bytes are there.
class FieldReader {
 public:
  FieldReader(std::span<const uint8_t> bytes, uint8_t type) : bytes_(bytes), type_(type) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw Error(ErrorKind::Input, std::string("tev IPC packet (") + type_name(type_) + "): " + what);
  }
  bool flag(const char* field) { return take(1, field)[0] != 0; }
  int32_t i32(const char* field) {
    const uint8_t* p = take(4, field);
    return static_cast<int32_t>(load_le32(p));
  }
  int64_t i64(const char* field) {
    return static_cast<int64_t>(load_little_endian<uint64_t>(take(8, field)));
  }
  std::string string(const char* field) {
    const void* nul = std::memchr(bytes_.data() + pos_, 0, bytes_.size() - pos_);
    if (!nul) fail(std::string("the ") + field + " string has no terminating NUL before the packet ends");
    const size_t n = static_cast<size_t>(static_cast<const uint8_t*>(nul) - (bytes_.data() + pos_));
    std::string s(reinterpret_cast<const char*>(bytes_.data() + pos_), n);
    pos_ += n + 1;
    return s;
  }
  // A count in [min, max], named in the error.
  int32_t count(const char* field, int32_t min, int32_t max) {
    const int32_t v = i32(field);
    if (v < min || v > max)
      fail(std::string(field) + " is " + std::to_string(v) + "; expected " + std::to_string(min) + " to " +
           std::to_string(max));
    return v;
  }
  size_t remaining() const { return bytes_.size() - pos_; }
  const uint8_t* here() const { return bytes_.data() + pos_; }

 private:
  const uint8_t* take(size_t n, const char* field) {
    if (remaining() < n)
      fail(std::string("the packet ends inside the ") + field + " field (" + std::to_string(remaining()) +
           " bytes left, " + std::to_string(n) + " needed)");
    const uint8_t* p = bytes_.data() + pos_;
    pos_ += n;
    return p;
  }

  std::span<const uint8_t> bytes_;
  size_t pos_ = 0;
  uint8_t type_;
};

float read_float(const uint8_t* p) {
  const uint32_t bits = load_le32(p);
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

UpdateImage parse_update(FieldReader& in, Type type, const TevLimits& limits) {
  UpdateImage u;
  u.grab_focus = in.flag("grab focus");
  u.name = in.string("image name");
  const int32_t n = type == Type::UpdateImage ? 1 : in.count("channel count", 1, limits.max_channels);
  for (int32_t c = 0; c < n; ++c) u.channel_names.push_back(in.string("channel name"));
  u.x = in.count("x", 0, std::numeric_limits<int32_t>::max());
  u.y = in.count("y", 0, std::numeric_limits<int32_t>::max());
  u.width = in.count("width", 1, std::numeric_limits<int32_t>::max());
  u.height = in.count("height", 1, std::numeric_limits<int32_t>::max());
  if (int64_t{u.x} + u.width > std::numeric_limits<int32_t>::max() ||
      int64_t{u.y} + u.height > std::numeric_limits<int32_t>::max())
    in.fail("the region " + std::to_string(u.x) + "," + std::to_string(u.y) + " " + std::to_string(u.width) + "x" +
            std::to_string(u.height) + " ends beyond 2^31 - 1");
  const int64_t pixels = int64_t{u.width} * u.height;
  // Decoded, an update is never larger than a packet could be (a stride of 0 repeats one value for every pixel).
  if (pixels > int64_t{limits.max_packet_bytes} / 4 / n)
    in.fail(std::to_string(u.width) + "x" + std::to_string(u.height) + " pixels of " + std::to_string(n) +
            " channels are more than " + std::to_string(limits.max_packet_bytes) + " bytes of floats");
  // Where each channel's values are, in floats from the start of the data.
  std::vector<int64_t> offsets(static_cast<size_t>(n)), strides(static_cast<size_t>(n), 1);
  if (type == Type::UpdateImageV3) {
    for (auto& o : offsets) o = in.i64("channel offset");
    for (auto& s : strides) s = in.i64("channel stride");
  } else {
    for (int32_t c = 0; c < n; ++c) offsets[static_cast<size_t>(c)] = pixels * c;
  }
  const int64_t available = static_cast<int64_t>(in.remaining() / sizeof(float));
  for (int32_t c = 0; c < n; ++c) {
    const int64_t offset = offsets[static_cast<size_t>(c)], stride = strides[static_cast<size_t>(c)];
    if (offset < 0 || stride < 0)
      in.fail("channel '" + u.channel_names[static_cast<size_t>(c)] + "' has offset " + std::to_string(offset) +
              " and stride " + std::to_string(stride) + "; both must be 0 or more");
    // The last value this channel reads, without overflow: offset + (pixels - 1) * stride < available.
    if (offset >= available || (pixels > 1 && stride > (available - 1 - offset) / (pixels - 1)))
      in.fail("the data holds " + std::to_string(available) + " floats, too few for " + std::to_string(u.width) +
              "x" + std::to_string(u.height) + " pixels of channel '" + u.channel_names[static_cast<size_t>(c)] +
              "' at offset " + std::to_string(offset) + ", stride " + std::to_string(stride));
  }
  const uint8_t* data = in.here();
  u.planes.assign(static_cast<size_t>(n), std::vector<float>(static_cast<size_t>(pixels)));
  for (int32_t c = 0; c < n; ++c) {
    const int64_t offset = offsets[static_cast<size_t>(c)], stride = strides[static_cast<size_t>(c)];
    float* plane = u.planes[static_cast<size_t>(c)].data();
    for (int64_t p = 0; p < pixels; ++p) plane[p] = read_float(data + (offset + p * stride) * 4);
  }
  return u;
}

}  // namespace

TevPacket parse_tev_packet(std::span<const uint8_t> packet, const TevLimits& limits) {
  if (packet.size() < 5)
    throw Error(ErrorKind::Input, "tev IPC packet of " + std::to_string(packet.size()) +
                                      " bytes: a packet has at least a 4-byte length and a type byte");
  const uint32_t length = load_le32(packet.data());
  if (length != packet.size())
    throw Error(ErrorKind::Input, "tev IPC packet: its length field says " + std::to_string(length) +
                                      " bytes, but it has " + std::to_string(packet.size()));
  if (length > limits.max_packet_bytes)
    throw Error(ErrorKind::Input, "tev IPC packet of " + std::to_string(length) + " bytes: more than the limit of " +
                                      std::to_string(limits.max_packet_bytes));
  const uint8_t type = packet[4];
  FieldReader in(packet.subspan(5), type);
  switch (static_cast<Type>(type)) {
    case Type::OpenImage: {
      OpenImage o;
      o.grab_focus = in.flag("grab focus");
      const std::string s = in.string("image path");
      // "PATH:CHANNELS", unless the colon is a Windows drive's ("C:/..." or "C:\...").
      const size_t colon = s.find_last_of(':');
      const bool drive = colon == 1 && s.size() >= 3 && (s[2] == '/' || s[2] == '\\');
      if (colon == std::string::npos || drive) {
        o.path = s;
      } else {
        o.path = s.substr(0, colon);
        o.channel_selector = s.substr(colon + 1);
      }
      return o;
    }
    case Type::OpenImageV2: {
      OpenImage o;
      o.grab_focus = in.flag("grab focus");
      o.path = in.string("image path");
      o.channel_selector = in.string("channel selector");
      return o;
    }
    case Type::ReloadImage: {
      ReloadImage r;
      r.grab_focus = in.flag("grab focus");
      r.name = in.string("image name");
      return r;
    }
    case Type::CloseImage: return CloseImage{in.string("image name")};
    case Type::CreateImage: {
      CreateImage c;
      c.grab_focus = in.flag("grab focus");
      c.name = in.string("image name");
      c.width = in.count("width", 1, std::numeric_limits<int32_t>::max());
      c.height = in.count("height", 1, std::numeric_limits<int32_t>::max());
      const int32_t n = in.count("channel count", 1, limits.max_channels);
      if (int64_t{c.width} * c.height > limits.max_image_values / n)
        in.fail(std::to_string(c.width) + "x" + std::to_string(c.height) + " with " + std::to_string(n) +
                " channels is more than " + std::to_string(limits.max_image_values) + " values");
      for (int32_t i = 0; i < n; ++i) c.channel_names.push_back(in.string("channel name"));
      return c;
    }
    case Type::UpdateImage:
    case Type::UpdateImageV2:
    case Type::UpdateImageV3: return parse_update(in, static_cast<Type>(type), limits);
    case Type::VectorGraphics: in.fail("vector graphics overlays are not supported by Residue's viewer");
  }
  throw Error(ErrorKind::Input, "tev IPC packet: unknown type " + std::to_string(type) + " (expected 0 to 8)");
}

void TevPacketStream::feed(std::span<const uint8_t> bytes) {
  if (start_ > 0 && start_ == buffer_.size()) {
    buffer_.clear();
    start_ = 0;
  }
  buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
}

std::optional<std::vector<uint8_t>> TevPacketStream::next() {
  if (buffered() < 4) return std::nullopt;
  const uint32_t length = load_le32(buffer_.data() + start_);
  if (length < 5 || length > limits_.max_packet_bytes)
    throw Error(ErrorKind::Input, "tev IPC stream: a packet declares " + std::to_string(length) +
                                      " bytes; expected 5 to " + std::to_string(limits_.max_packet_bytes) +
                                      " (not a tev client, or out of step)");
  if (buffered() < length) return std::nullopt;
  std::vector<uint8_t> packet(buffer_.begin() + static_cast<std::ptrdiff_t>(start_),
                              buffer_.begin() + static_cast<std::ptrdiff_t>(start_ + length));
  start_ += length;
  // Drop what was returned once it is most of the buffer, so that a long stream does not grow it.
  if (start_ > buffer_.size() / 2) {
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(start_));
    start_ = 0;
  }
  return packet;
}

}  // namespace residue::ipc
