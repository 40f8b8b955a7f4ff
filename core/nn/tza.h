// TZA files: Intel Open Image Denoise's "Tensor Archive", the format its trained networks ship in
// (resources/models/oidn/*.tza).
//
// Little-endian: u16 magic 0x41D7, u8 major version (2), u8 minor, u64 offset of the table. At the table: u32
// tensor count, then per tensor: u16 name length and the UTF-8 name, u8 ndims, ndims x u32 dims, ndims ASCII
// layout characters ("oihw", "x"), one dtype character ('f' float32, 'h' float16, 'b' int8, 'B' uint8) and the
// u64 byte offset of its data from the start of the file. The data is dense and row-major in the given shape.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace residue::nn {

struct TzaTensor {
  std::vector<int64_t> shape;
  std::string layout;          // e.g. "oihw", "x"
  std::vector<float> values;   // converted to float32 (float16 converted exactly, including subnormals, inf, nan)
};

struct TzaFile {
  std::map<std::string, TzaTensor> tensors;
};

// Throws residue::Error(ErrorKind::Input) naming the file, the tensor where it applies, and what was expected:
// bad magic, unsupported version, truncated header, table or data, offsets or sizes out of range, unknown dtype,
// a layout that does not have one character per dimension, duplicate names, no tensors.
TzaFile read_tza(const std::filesystem::path& path);

// The same on bytes already in memory; `where` names the source in errors (e.g. "TZA file 'x.tza'").
TzaFile parse_tza(const std::vector<uint8_t>& bytes, const std::string& where);

}  // namespace residue::nn
