// safetensors files: an 8-byte little-endian header length, a JSON header naming each tensor's dtype, shape
// and byte range, then the raw little-endian data. Simple, safe to parse, and read by Python as is
// (`safetensors.numpy.load_file`, or 20 lines of NumPy).
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace residue::nn {

struct Tensor {
  std::string dtype = "F32";   // as stored: F32, F16, BF16 (converted to float on load)
  std::vector<int64_t> shape;
  std::vector<float> values;   // always float in memory
  int64_t numel() const;  // -1 for a negative dimension or a product beyond int64
};

struct SafetensorsFile {
  std::map<std::string, std::string> metadata;  // "__metadata__": strings only, by the format's rule
  std::map<std::string, Tensor> tensors;
};

// Throws residue::Error(Input) naming the file and what is wrong (truncated, bad header, bad dtype, ...).
SafetensorsFile read_safetensors(const std::filesystem::path& path);

// Writes F32 tensors atomically (never replacing an existing file unless `overwrite`).
void write_safetensors(const std::filesystem::path& path, const SafetensorsFile& file, bool overwrite);

// "[64, 9, 3, 3]": a tensor's shape in error messages.
std::string shape_to_string(const std::vector<int64_t>& shape);

// Throws Error(Input) "<where>: tensor "<name>" has N non-finite values (NaN or Inf); expected finite weights"
// when any value is NaN or infinite: such a network would denoise every pixel to NaN (then black).
void check_finite(const std::vector<float>& values, const std::string& where, const std::string& name);

}  // namespace residue::nn
