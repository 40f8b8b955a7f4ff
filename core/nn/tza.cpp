#include "core/nn/tza.h"

#include <bit>
#include <cstdio>
#include <fstream>
#include <limits>

#include <Imath/half.h>

#include "core/util/error.h"
#include "core/util/input_file.h"
#include "core/util/little_endian.h"

namespace residue::nn {
namespace {

constexpr uint16_t kMagic = 0x41D7;
constexpr uint64_t kHeaderSize = 12;  // magic, major, minor, table offset



// Reads little-endian fields from the byte vector, throwing a message naming `where` when they run out.
class Cursor {
 public:
  Cursor(const std::vector<uint8_t>& bytes, uint64_t pos, const std::string& where)
      : bytes_(bytes), pos_(pos), where_(where) {}

  uint64_t pos() const { return pos_; }

  // Little-endian unsigned integer of N bytes.
  template <typename T>
  T read(const std::string& what) {
    need(sizeof(T), what);
    const T v = load_little_endian<T>(bytes_.data() + pos_);
    pos_ += sizeof(T);
    return v;
  }

  std::string read_string(uint64_t n, const std::string& what) {
    need(n, what);
    std::string s(reinterpret_cast<const char*>(bytes_.data() + pos_), static_cast<size_t>(n));
    pos_ += n;
    return s;
  }

 private:
  void need(uint64_t n, const std::string& what) const {
    if (pos_ > bytes_.size() || n > bytes_.size() - pos_)
      throw Error(ErrorKind::Input, where_ + " is truncated: its tensor table ends inside " + what + " (at byte " +
                                        std::to_string(pos_) + ", " + std::to_string(n) + " more bytes needed, file has " +
                                        std::to_string(bytes_.size()) + ")");
  }

  const std::vector<uint8_t>& bytes_;
  uint64_t pos_;
  const std::string& where_;
};

size_t dtype_size(char dtype) {
  switch (dtype) {
    case 'f': return 4;
    case 'h': return 2;
    case 'b':
    case 'B': return 1;
    default: return 0;
  }
}

std::string printable(char c) {
  const auto u = static_cast<unsigned char>(c);
  if (u >= 0x20 && u < 0x7F) return std::string("'") + c + "'";
  static const char* hex = "0123456789ABCDEF";
  return std::string("byte 0x") + hex[u >> 4] + hex[u & 0xF];
}

}  // namespace

TzaFile parse_tza(const std::vector<uint8_t>& bytes, const std::string& where) {
  static_assert(sizeof(float) == 4);
  const uint64_t size = bytes.size();
  if (size < kHeaderSize)
    throw Error(ErrorKind::Input, where + " is truncated: " + std::to_string(size) + " bytes, shorter than the " +
                                      std::to_string(kHeaderSize) + "-byte TZA header");
  Cursor header(bytes, 0, where);
  const auto magic = header.read<uint16_t>("the header");
  if (magic != kMagic) {
    char found[8];
    std::snprintf(found, sizeof found, "0x%04X", static_cast<unsigned>(magic));
    throw Error(ErrorKind::Input, where + " is not a TZA file: bad magic " + found + ", expected 0x41D7");
  }
  const auto major = header.read<uint8_t>("the header");
  const auto minor = header.read<uint8_t>("the header");
  if (major != 2)
    throw Error(ErrorKind::Input, where + " has TZA version " + std::to_string(major) + "." + std::to_string(minor) +
                                      ", which is not supported; expected version 2.x");
  const auto table_offset = header.read<uint64_t>("the header");
  if (table_offset < kHeaderSize || table_offset > size)
    throw Error(ErrorKind::Input, where + ": the tensor table offset " + std::to_string(table_offset) +
                                      " is out of range; expected " + std::to_string(kHeaderSize) + " to " +
                                      std::to_string(size) + " (the file size)" +
                                      (table_offset > size ? "; the file may be truncated" : ""));

  Cursor table(bytes, table_offset, where);
  const auto count = table.read<uint32_t>("the tensor count");
  if (count == 0) throw Error(ErrorKind::Input, where + " holds no tensors; expected at least one");

  TzaFile file;
  // Bytes claimed by the tensors so far. Each tensor's data must lie in the file, and together they may not claim
  // more than the file holds: tensors that share (overlap) their data would otherwise let a small file expand to
  // count x its size in floats (a 1 MB table of 50,000 entries aliasing 1 MB of data: 200 GB).
  uint64_t claimed = 0;
  for (uint32_t i = 0; i < count; ++i) {
    const std::string nth = "tensor #" + std::to_string(i + 1) + " of " + std::to_string(count);
    const auto name_length = table.read<uint16_t>("the name length of " + nth);
    const std::string name = table.read_string(name_length, "the name of " + nth);
    const std::string tensor = "tensor \"" + name + "\"";
    if (file.tensors.count(name))
      throw Error(ErrorKind::Input, where + ": " + tensor + " appears twice (" + nth + "); expected unique names");

    const auto ndims = table.read<uint8_t>("the rank of " + tensor);
    TzaTensor t;
    t.shape.reserve(ndims);
    for (unsigned d = 0; d < ndims; ++d) t.shape.push_back(table.read<uint32_t>("the shape of " + tensor));
    const std::string layout = table.read_string(ndims, "the layout of " + tensor);
    // One printable character per dimension; a NUL or control character means a shorter (or broken) layout.
    size_t layout_length = 0;
    while (layout_length < layout.size() && static_cast<unsigned char>(layout[layout_length]) > 0x20 &&
           static_cast<unsigned char>(layout[layout_length]) < 0x7F)
      ++layout_length;
    if (layout_length != ndims)
      throw Error(ErrorKind::Input, where + ": " + tensor + " has layout \"" + layout.substr(0, layout_length) +
                                        "\" of " + std::to_string(layout_length) + " characters, expected " +
                                        std::to_string(ndims) + " (one letter per dimension)");
    t.layout = layout;

    const char dtype = table.read_string(1, "the dtype of " + tensor)[0];
    const size_t elem = dtype_size(dtype);
    if (elem == 0)
      throw Error(ErrorKind::Input, where + ": " + tensor + " has unknown dtype " + printable(dtype) +
                                        "; expected 'f' (float32), 'h' (float16), 'b' (int8) or 'B' (uint8)");
    const auto data_offset = table.read<uint64_t>("the data offset of " + tensor);

    // Element count and byte size, checked against 64-bit overflow at every step.
    uint64_t numel = 1;
    for (int64_t d : t.shape) {
      const auto dim = static_cast<uint64_t>(d);
      if (dim != 0 && numel > std::numeric_limits<uint64_t>::max() / dim)
        throw Error(ErrorKind::Input, where + ": " + tensor + " has a shape whose element count overflows 64 bits");
      numel *= dim;
    }
    if (numel > std::numeric_limits<uint64_t>::max() / elem)
      throw Error(ErrorKind::Input, where + ": " + tensor + " has a byte size that overflows 64 bits");
    const uint64_t byte_size = numel * elem;
    if (data_offset > size)
      throw Error(ErrorKind::Input, where + ": " + tensor + " has data offset " + std::to_string(data_offset) +
                                        ", past the end of the file (" + std::to_string(size) + " bytes)");
    if (byte_size > size - data_offset)
      throw Error(ErrorKind::Input, where + " is truncated: " + tensor + " needs " + std::to_string(byte_size) +
                                        " bytes from offset " + std::to_string(data_offset) + ", but the file has " +
                                        std::to_string(size) + " bytes");

    if (byte_size > size - claimed)
      throw Error(ErrorKind::Input, where + ": " + tensor + " brings the tensors' data to more than the file's " +
                                        std::to_string(size) + " bytes; expected each tensor's data apart (" + nth + ")");
    claimed += byte_size;

    const uint8_t* src = bytes.data() + data_offset;
    t.values.resize(static_cast<size_t>(numel));
    for (size_t k = 0; k < t.values.size(); ++k) {
      switch (dtype) {
        case 'f': {
          uint32_t u = 0;
          for (int b = 0; b < 4; ++b) u |= static_cast<uint32_t>(src[4 * k + b]) << (8 * b);
          t.values[k] = std::bit_cast<float>(u);
          break;
        }
        case 'h':
          t.values[k] = static_cast<float>(Imath::half(Imath::half::FromBits, static_cast<uint16_t>(src[2 * k] | (src[2 * k + 1] << 8))));
          break;
        case 'b': t.values[k] = static_cast<float>(static_cast<int8_t>(src[k])); break;
        default: t.values[k] = static_cast<float>(src[k]); break;
      }
    }
    file.tensors.emplace(name, std::move(t));
  }
  return file;
}

TzaFile read_tza(const std::filesystem::path& path) {
  const std::string where = "TZA file '" + path.string() + "'";
  check_input_file(path, "TZA file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(ErrorKind::Input, "cannot open " + where);
  std::error_code ec;
  const auto file_size = std::filesystem::file_size(path, ec);
  if (ec) throw Error(ErrorKind::Input, "cannot read the size of " + where + ": " + ec.message());
  std::vector<uint8_t> bytes(static_cast<size_t>(file_size));
  if (!bytes.empty() && !in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size())))
    throw Error(ErrorKind::Input, "cannot read " + where);
  return parse_tza(bytes, where);
}

}  // namespace residue::nn
