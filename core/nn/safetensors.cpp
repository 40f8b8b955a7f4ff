#include "core/nn/safetensors.h"

#include <algorithm>
#include <cmath>

#include <bit>
#include <cstring>
#include <fstream>

#include <Imath/half.h>
#include <nlohmann/json.hpp>

#include "core/io/atomic_file.h"
#include "core/util/error.h"
#include "core/util/input_file.h"

namespace residue::nn {
namespace {

static_assert(std::endian::native == std::endian::little, "safetensors data is little-endian");

float bf16_to_float(uint16_t v) {
  const uint32_t bits = static_cast<uint32_t>(v) << 16;
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

}  // namespace

int64_t Tensor::numel() const {
  int64_t n = 1;
  for (int64_t d : shape)
    if (d < 0 || __builtin_mul_overflow(n, d, &n)) return -1;
  return n;
}

SafetensorsFile read_safetensors(const std::filesystem::path& path) {
  const std::string where = "model file '" + path.string() + "'";
  check_input_file(path, "model file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(ErrorKind::Input, "cannot open " + where);
  const auto file_size = static_cast<uint64_t>(std::filesystem::file_size(path));
  uint64_t header_size = 0;
  if (!in.read(reinterpret_cast<char*>(&header_size), 8) || header_size > file_size - 8)
    throw Error(ErrorKind::Input, where + " is truncated or not a safetensors file (bad header length)");
  std::string header(header_size, '\0');
  in.read(header.data(), static_cast<std::streamsize>(header_size));
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(header);
  } catch (const std::exception& e) {
    throw Error(ErrorKind::Input, where + ": the header is not valid JSON (" + e.what() + ")");
  }
  const uint64_t data_size = file_size - 8 - header_size;
  std::vector<char> data(data_size);
  in.read(data.data(), static_cast<std::streamsize>(data_size));

  SafetensorsFile f;
  // Bytes claimed by the tensors so far: the format lays them out apart, so together they fit in the data; tensors
  // sharing one range would otherwise let a small file expand to count x its size in floats.
  uint64_t claimed = 0;
  try {
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (it.key() == "__metadata__") {
        for (auto m = it->begin(); m != it->end(); ++m) f.metadata[m.key()] = m->get<std::string>();
        continue;
      }
      Tensor t;
      t.dtype = it->at("dtype").get<std::string>();
      // Integers only: a number such as 4.3e81 would be converted out of range (undefined behaviour; found by
      // fuzz_safetensors).
      auto integers = [&](const char* field, bool non_negative) {
        const auto& array = it->at(field);
        if (!array.is_array())
          throw Error(ErrorKind::Input, where + ": tensor \"" + it.key() + "\": " + field + " is not an array");
        for (const auto& v : array)
          if (!(non_negative ? v.is_number_unsigned() : v.is_number_integer()))
            throw Error(ErrorKind::Input, where + ": tensor \"" + it.key() + "\": " + field + " holds " + v.dump() +
                                              "; expected " + (non_negative ? "integers >= 0" : "integers"));
        return array;
      };
      t.shape = integers("shape", false).get<std::vector<int64_t>>();
      const auto offsets = integers("data_offsets", true).get<std::vector<uint64_t>>();
      const size_t elem = t.dtype == "F32" ? 4 : (t.dtype == "F16" || t.dtype == "BF16") ? 2 : 0;
      if (elem == 0)
        throw Error(ErrorKind::Input, where + ": tensor \"" + it.key() + "\" has dtype " + t.dtype +
                                          "; expected F32, F16 or BF16");
      if (t.numel() < 0 || static_cast<uint64_t>(t.numel()) > data_size / elem)
        throw Error(ErrorKind::Input, where + ": tensor \"" + it.key() + "\" has shape " + shape_to_string(t.shape) +
                                          ", more values than the file holds");
      const uint64_t n = static_cast<uint64_t>(t.numel());
      if (offsets.size() != 2 || offsets[1] < offsets[0] || offsets[1] - offsets[0] != n * elem)
        throw Error(ErrorKind::Input, where + ": tensor \"" + it.key() + "\" has a byte range that does not fit its shape");
      if (offsets[1] > data_size)
        throw Error(ErrorKind::Input, where + " is truncated: tensor \"" + it.key() + "\" ends at byte " +
                                          std::to_string(offsets[1]) + " of " + std::to_string(data_size));
      if (n * elem > data_size - claimed)
        throw Error(ErrorKind::Input, where + ": tensor \"" + it.key() + "\" brings the tensors' data to more than the " +
                                          std::to_string(data_size) + " bytes the file holds; expected each tensor's "
                                          "byte range apart");
      claimed += n * elem;
      const char* src = data.data() + offsets[0];
      t.values.resize(n);
      for (uint64_t i = 0; i < n; ++i) {
        if (elem == 4) {
          std::memcpy(&t.values[i], src + 4 * i, 4);
        } else {
          uint16_t v;
          std::memcpy(&v, src + 2 * i, 2);
          t.values[i] = t.dtype == "BF16" ? bf16_to_float(v) : static_cast<float>(Imath::half(Imath::half::FromBits, v));
        }
      }
      f.tensors[it.key()] = std::move(t);
    }
  } catch (const nlohmann::json::exception& e) {
    throw Error(ErrorKind::Input, where + ": malformed header (" + e.what() + ")");
  }
  return f;
}

void write_safetensors(const std::filesystem::path& path, const SafetensorsFile& file, bool overwrite) {
  nlohmann::json j;
  if (!file.metadata.empty()) j["__metadata__"] = file.metadata;
  uint64_t offset = 0;
  for (const auto& [name, t] : file.tensors) {
    const uint64_t bytes = t.values.size() * 4;
    j[name] = {{"dtype", "F32"}, {"shape", t.shape}, {"data_offsets", {offset, offset + bytes}}};
    offset += bytes;
  }
  std::string header = j.dump();
  header.append((8 - header.size() % 8) % 8, ' ');  // align the data to 8 bytes, as the reference writer does
  io::write_atomically(path, overwrite, [&](const std::filesystem::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    const uint64_t size = header.size();
    out.write(reinterpret_cast<const char*>(&size), 8);
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    for (const auto& [name, t] : file.tensors)
      out.write(reinterpret_cast<const char*>(t.values.data()), static_cast<std::streamsize>(t.values.size() * 4));
    if (!out) throw Error(ErrorKind::Output, "cannot write model file '" + path.string() + "'");
  });
}

std::string shape_to_string(const std::vector<int64_t>& shape) {
  std::string s = "[";
  for (size_t i = 0; i < shape.size(); ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
  return s + "]";
}

void check_finite(const std::vector<float>& values, const std::string& where, const std::string& name) {
  const auto bad = std::count_if(values.begin(), values.end(), [](float v) { return !std::isfinite(v); });
  if (bad > 0)
    throw Error(ErrorKind::Input, where + ": tensor \"" + name + "\" has " + std::to_string(bad) +
                                      " non-finite values (NaN or Inf); expected finite weights");
}

}  // namespace residue::nn
