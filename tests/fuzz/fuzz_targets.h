// What each libFuzzer harness does with one input, shared by the harnesses (tests/fuzz/fuzz_*.cpp) and by the
// regression tests (tests/test_fuzz_regressions.cpp), which replay the seed corpora and every crash the fuzzers
// found through exactly the same code. residue::Error (and any std::exception) is an expected answer to bad
// bytes; crashes, leaks and undefined behaviour (caught by ASan/UBSan in the fuzz and asan builds) are bugs.
#pragma once

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "core/aov/aov_loader.h"
#include "core/aov/channel_mapping.h"
#include "core/nn/model_file.h"
#include "core/nn/oidn_network.h"
#include "core/nn/safetensors.h"
#include "core/nn/tza.h"

namespace residue::fuzz {

// /dev/shm/residue-fuzz-<pid>/ (or the temp dir when /dev/shm is absent): one per process, so that parallel jobs
// (-jobs=N) never share files and no loader finds a neighbour by a naming convention (reference.exr, ...).
// Removed at exit (a crashed run leaves it behind).
inline const std::filesystem::path& scratch_dir() {
  struct Scratch {
    std::filesystem::path dir;
    Scratch() {
      const std::filesystem::path base = std::filesystem::is_directory("/dev/shm") ? std::filesystem::path("/dev/shm")
                                                                                    : std::filesystem::temp_directory_path();
      dir = base / ("residue-fuzz-" + std::to_string(::getpid()));
      std::filesystem::create_directories(dir);
    }
    ~Scratch() {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  };
  static const Scratch scratch;
  return scratch.dir;
}

// The input as a file of the given name in scratch_dir(), for readers that take a path.
inline std::filesystem::path write_input(const std::string& name, const uint8_t* data, size_t size) {
  const auto path = scratch_dir() / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

// The loader has no size limit of its own (a 100000 x 100000 render is legitimate input); a fuzzed header may
// declare one, and allocating and filling it under ASan only slows the fuzzer down (a first 10-minute run with a
// 16 Mi-value limit made 4 inputs a second at 2 GB RSS). Inputs with a subimage whose data or display window holds
// more than this many channel values (4 MiB of floats), or with over 16 subimages, are skipped.
constexpr int64_t kMaxExrValues = int64_t{1} << 20;

// OpenEXR 3.1 (Debian 12) allocates an attribute's declared size before reading it: a 2.6 KB file whose header
// declares a 1.9 GB string attribute makes it allocate (and zero) 1.9 GB, found by both 10-minute runs of
// fuzz_exr_loader (see docs/RELIABILITY.md). That is OpenEXR's, not Residue's, and it ends every run in an
// out-of-memory at once; so the harness skips inputs whose header declares an attribute larger than the file.
// Walks the headers (several for a multipart file, an empty one ending the list): name, type, int32 size, value.
inline bool exr_attribute_sizes_fit(const uint8_t* data, size_t size) {
  if (size < 8) return true;
  // OpenEXR reads fixed-size attributes (box2i, ...) by their type, whatever size the header declares, so after a
  // mutated one its position differs from the walk below; so also look at every "string" type name anywhere,
  // with the int32 size after it: both OOM inputs of the second run are caught this way.
  for (const char* type : {"string", "stringvector"}) {
    const size_t len = std::strlen(type) + 1;
    for (size_t p = 0; p + len + 4 <= size; ++p) {
      if (std::memcmp(data + p, type, len) != 0) continue;
      const size_t q = p + len;
      const uint32_t n = uint32_t{data[q]} | uint32_t{data[q + 1]} << 8 | uint32_t{data[q + 2]} << 16 |
                         uint32_t{data[q + 3]} << 24;
      if (n > size - q - 4) return false;
    }
  }
  const bool multipart = (data[5] & 0x10) != 0;  // version field bit 12
  size_t pos = 8;
  auto cstring = [&](size_t& p) -> std::optional<size_t> {  // length of the NUL-terminated string at p
    const void* nul = std::memchr(data + p, 0, size - p);
    if (!nul) return std::nullopt;
    const size_t n = static_cast<size_t>(static_cast<const uint8_t*>(nul) - (data + p));
    p += n + 1;
    return n;
  };
  for (int header = 0; pos < size; ++header) {
    bool empty = true;
    for (;;) {
      if (pos >= size) return true;
      const auto name = cstring(pos);
      if (!name) return true;
      if (*name == 0) break;  // end of this header
      empty = false;
      if (pos >= size || !cstring(pos)) return true;  // type
      if (size - pos < 4) return true;
      const uint32_t n = uint32_t{data[pos]} | uint32_t{data[pos + 1]} << 8 | uint32_t{data[pos + 2]} << 16 |
                         uint32_t{data[pos + 3]} << 24;
      pos += 4;
      if (n > size - pos) return false;
      pos += n;
    }
    if (!multipart || empty) return true;
  }
  return true;
}

inline bool exr_small_enough(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    (void)OIIO::geterror();  // clear OpenImageIO's per-thread error so that it does not pile up
    return true;             // the loader reports the error itself
  }
  for (int sub = 0; in->seek_subimage(sub, 0); ++sub) {
    if (sub >= 16) return false;
    const OIIO::ImageSpec& s = in->spec();
    const int64_t ch = std::max(1, s.nchannels);
    const int64_t data = int64_t{std::max(0, s.width)} * std::max(0, s.height) * std::max(1, s.depth);
    const int64_t full = int64_t{std::max(0, s.full_width)} * std::max(0, s.full_height);
    if (data > kMaxExrValues / ch || full > kMaxExrValues / ch) return false;
  }
  (void)in->geterror();
  return true;
}

// fuzz_exr_loader: the bytes as input.exr, through list_channels and load_aov_stack (OpenImageIO, channel
// naming, multipart, data and display windows, normalisation).
inline void exr_loader_one(const uint8_t* data, size_t size) {
  if (!exr_attribute_sizes_fit(data, size)) return;
  const auto path = write_input("input.exr", data, size);
  if (!exr_small_enough(path.string())) return;
  try {
    (void)list_channels(path);
  } catch (const std::exception&) {
  }
  try {
    (void)load_aov_stack({path}, LoadOptions{});
  } catch (const std::exception&) {
  }
  (void)OIIO::geterror();
}

// fuzz_safetensors: read_safetensors, then (when that succeeds) load_model: metadata, tensor names and shapes,
// batch-norm folding, the inference graph.
inline void safetensors_one(const uint8_t* data, size_t size) {
  const auto path = write_input("model.safetensors", data, size);
  try {
    (void)nn::read_safetensors(path);
  } catch (const std::exception&) {
    return;  // load_model reads the same way and would fail the same way
  }
  try {
    (void)nn::load_model(path);
  } catch (const std::exception&) {
  }
}

// fuzz_tza: parse_tza on the bytes, then (when that succeeds) the OIDN UNet built from the tensors, with 9 input
// channels (rt_hdr_alb_nrm) and 3 (rt_hdr), as load_model does.
inline void tza_one(const uint8_t* data, size_t size) {
  const std::vector<uint8_t> bytes(data, data + size);
  nn::TzaFile file;
  try {
    file = nn::parse_tza(bytes, "fuzz input");
  } catch (const std::exception&) {
    return;
  }
  for (int channels : {9, 3}) {
    try {
      (void)nn::oidn_graph(file, channels, "fuzz input");
    } catch (const std::exception&) {
    }
  }
}

// fuzz_channel_mapping: the input split at its first NUL byte: before it, a --map flag (ROLE=[FILE:]CHANNELS);
// after it (or the whole input when there is no NUL), a JSON mapping file (--mapping FILE.json).
inline void channel_mapping_one(const uint8_t* data, size_t size) {
  const auto* nul = size ? static_cast<const uint8_t*>(std::memchr(data, 0, size)) : nullptr;
  const size_t flag_size = nul ? static_cast<size_t>(nul - data) : 0;
  const uint8_t* json = nul ? nul + 1 : data;
  const size_t json_size = nul ? size - flag_size - 1 : size;
  ChannelMapping from_flag;
  if (nul) {
    try {
      from_flag.add_flag(std::string(reinterpret_cast<const char*>(data), flag_size));
    } catch (const std::exception&) {
    }
  }
  const auto path = write_input("mapping.json", json, json_size);
  try {
    auto m = ChannelMapping::from_json_file(path);
    m.merge(from_flag);
  } catch (const std::exception&) {
  }
}

}  // namespace residue::fuzz
