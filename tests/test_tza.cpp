// core/nn/tza: Open Image Denoise's Tensor Archive reader, on the shipped OIDN weights and on archives written here.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>

#include <Imath/half.h>

#include "core/nn/tza.h"
#include "core/util/error.h"
#include "support/test_support.h"

namespace residue {
namespace {

const std::filesystem::path kOidnDir = testing::oidn_dir();

// --- a small TZA writer, with hooks to break the result ----------------------------------------------------------

struct Spec {
  std::string name;
  std::vector<uint32_t> dims;
  std::string layout;
  char dtype = 'f';
  std::vector<uint8_t> data;          // raw little-endian data
  std::optional<uint64_t> offset;     // data offset to write instead of the real one
};

void put16(std::vector<uint8_t>& b, uint16_t v) {
  for (int i = 0; i < 2; ++i) b.push_back(static_cast<uint8_t>(v >> (8 * i)));
}
void put32(std::vector<uint8_t>& b, uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<uint8_t>(v >> (8 * i)));
}
void put64(std::vector<uint8_t>& b, uint64_t v) {
  for (int i = 0; i < 8; ++i) b.push_back(static_cast<uint8_t>(v >> (8 * i)));
}

std::vector<uint8_t> f32_bytes(const std::vector<float>& v) {
  std::vector<uint8_t> b;
  for (float f : v) put32(b, std::bit_cast<uint32_t>(f));
  return b;
}
std::vector<uint8_t> f16_bytes(const std::vector<uint16_t>& v) {
  std::vector<uint8_t> b;
  for (uint16_t h : v) put16(b, h);
  return b;
}

// Header, then each tensor's data (64-byte aligned, as OIDN writes), then the table.
std::vector<uint8_t> build_tza(const std::vector<Spec>& specs, uint8_t major = 2, uint8_t minor = 0,
                               std::optional<uint32_t> count = std::nullopt) {
  std::vector<uint8_t> b;
  put16(b, 0x41D7);
  b.push_back(major);
  b.push_back(minor);
  put64(b, 0);  // table offset, patched below
  std::vector<uint64_t> offsets;
  for (const auto& s : specs) {
    while (b.size() % 64) b.push_back(0);
    offsets.push_back(b.size());
    b.insert(b.end(), s.data.begin(), s.data.end());
  }
  const uint64_t table = b.size();
  for (int i = 0; i < 8; ++i) b[4 + i] = static_cast<uint8_t>(table >> (8 * i));
  put32(b, count.value_or(static_cast<uint32_t>(specs.size())));
  for (size_t k = 0; k < specs.size(); ++k) {
    const auto& s = specs[k];
    put16(b, static_cast<uint16_t>(s.name.size()));
    b.insert(b.end(), s.name.begin(), s.name.end());
    b.push_back(static_cast<uint8_t>(s.dims.size()));
    for (uint32_t d : s.dims) put32(b, d);
    b.insert(b.end(), s.layout.begin(), s.layout.end());
    b.push_back(static_cast<uint8_t>(s.dtype));
    put64(b, s.offset.value_or(offsets[k]));
  }
  return b;
}

Spec good_f32(const std::string& name = "conv.weight") {
  return {name, {2, 1, 1, 2}, "oihw", 'f', f32_bytes({1.0f, -2.5f, 3.25f, 1e-30f}), std::nullopt};
}

void write_file(const std::filesystem::path& p, const std::vector<uint8_t>& bytes) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

// Writes `bytes` to a file named `file_name`, reads it, and expects an Input error whose message contains the file
// name and each of `parts`.
void expect_input_error(const std::vector<uint8_t>& bytes, const std::string& file_name,
                        const std::vector<std::string>& parts) {
  testing::TempDir tmp;
  const auto path = tmp / file_name;
  write_file(path, bytes);
  try {
    nn::read_tza(path);
    ADD_FAILURE() << file_name << ": read_tza did not throw";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Input) << e.what();
    const std::string msg = e.what();
    EXPECT_NE(msg.find(file_name), std::string::npos) << "message does not name the file: " << msg;
    for (const auto& p : parts) EXPECT_NE(msg.find(p), std::string::npos) << "message lacks \"" << p << "\": " << msg;
  }
}

// --- the shipped OIDN weights -------------------------------------------------------------------------------------

struct Shipped {
  const char* file;
  size_t tensors;
  const char* first;          // first conv
  std::vector<int64_t> first_shape;
  std::vector<int64_t> dec1a_shape;
  const char* last;           // last conv
  std::vector<int64_t> last_shape;
  size_t parameters;
};

const std::vector<Shipped>& shipped() {
  static const std::vector<Shipped> s = {
      {"rt_hdr_alb_nrm.tza", 32, "enc_conv0", {32, 9, 3, 3}, {64, 73, 3, 3}, "dec_conv0", {3, 32, 3, 3}, 919'811},
      {"rt_hdr_alb.tza", 32, "enc_conv0", {32, 6, 3, 3}, {64, 70, 3, 3}, "dec_conv0", {3, 32, 3, 3}, 917'219},
      {"rt_hdr.tza", 32, "enc_conv0", {32, 3, 3, 3}, {64, 67, 3, 3}, "dec_conv0", {3, 32, 3, 3}, 914'627},
      {"rt_alb_large.tza", 38, "enc_conv1a", {64, 3, 3, 3}, {64, 99, 3, 3}, "dec_conv1c", {3, 64, 3, 3}, 3'841'475},
      {"rt_nrm_large.tza", 38, "enc_conv1a", {64, 3, 3, 3}, {64, 99, 3, 3}, "dec_conv1c", {3, 64, 3, 3}, 3'841'475},
      {"rt_hdr_calb_cnrm_large.tza", 38, "enc_conv1a", {64, 9, 3, 3}, {64, 105, 3, 3}, "dec_conv1c", {3, 64, 3, 3},
       3'848'387},
  };
  return s;
}

TEST(Tza, ReadsEveryShippedOidnNetwork) {
  for (const auto& s : shipped()) {
    SCOPED_TRACE(s.file);
    const nn::TzaFile f = nn::read_tza(kOidnDir / s.file);
    EXPECT_EQ(f.tensors.size(), s.tensors);
    ASSERT_TRUE(f.tensors.count(std::string(s.first) + ".weight"));
    EXPECT_EQ(f.tensors.at(std::string(s.first) + ".weight").shape, s.first_shape);
    EXPECT_EQ(f.tensors.at(std::string(s.first) + ".bias").shape, std::vector<int64_t>{s.first_shape[0]});
    ASSERT_TRUE(f.tensors.count("dec_conv1a.weight"));
    EXPECT_EQ(f.tensors.at("dec_conv1a.weight").shape, s.dec1a_shape);
    ASSERT_TRUE(f.tensors.count(std::string(s.last) + ".weight"));
    EXPECT_EQ(f.tensors.at(std::string(s.last) + ".weight").shape, s.last_shape);
    size_t parameters = 0;
    for (const auto& [name, t] : f.tensors) {
      SCOPED_TRACE(name);
      const bool weight = name.ends_with(".weight");
      EXPECT_TRUE(weight || name.ends_with(".bias"));
      EXPECT_EQ(t.layout, weight ? "oihw" : "x");
      EXPECT_EQ(t.shape.size(), weight ? 4u : 1u);
      if (weight) {  // every conv of OIDN's RT networks is 3x3
        EXPECT_EQ(t.shape[2], 3);
        EXPECT_EQ(t.shape[3], 3);
      }
      int64_t n = 1;
      for (int64_t d : t.shape) n *= d;
      ASSERT_EQ(t.values.size(), static_cast<size_t>(n));
      size_t non_finite = 0;
      for (float v : t.values) non_finite += std::isfinite(v) ? 0 : 1;
      EXPECT_EQ(non_finite, 0u);
      parameters += t.values.size();
    }
    EXPECT_EQ(parameters, s.parameters);
  }
  // rt_alb_large and rt_nrm_large have the same shapes but different values.
  const auto alb = nn::read_tza(kOidnDir / "rt_alb_large.tza");
  const auto nrm = nn::read_tza(kOidnDir / "rt_nrm_large.tza");
  EXPECT_NE(alb.tensors.at("enc_conv1a.weight").values, nrm.tensors.at("enc_conv1a.weight").values);
}

// --- round trips ----------------------------------------------------------------------------------------------------

TEST(Tza, RoundTripsFloat32AndFloat16) {
  const std::vector<float> f32 = {0.0f, -0.0f, 1.0f, -3.5f, 1e-40f /* subnormal */, std::numeric_limits<float>::max(),
                                  std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity()};
  // Halves: 0, -0, 1, -2, the smallest subnormal (2^-24), the largest subnormal, the smallest normal (2^-14),
  // 65504 (max), +inf, -inf, 1/3 rounded, a NaN.
  const std::vector<uint16_t> f16 = {0x0000, 0x8000, 0x3C00, 0xC000, 0x0001, 0x03FF,
                                     0x0400, 0x7BFF, 0x7C00, 0xFC00, 0x3555, 0x7E00};
  const std::vector<float> f16_expected = {0.0f, -0.0f, 1.0f, -2.0f, std::ldexp(1.0f, -24), std::ldexp(1023.0f, -24),
                                           std::ldexp(1.0f, -14), 65504.0f, std::numeric_limits<float>::infinity(),
                                           -std::numeric_limits<float>::infinity(), 0.333251953125f,
                                           std::numeric_limits<float>::quiet_NaN()};
  const std::vector<uint8_t> i8 = {0x00, 0x7F, 0x80, 0xFF};
  const auto bytes = build_tza({
      {"a.weight", {2, 2, 1, 2}, "oihw", 'f', f32_bytes(f32), std::nullopt},
      {"a.bias", {12}, "x", 'h', f16_bytes(f16), std::nullopt},
      {"q.signed", {4}, "x", 'b', i8, std::nullopt},
      {"q.unsigned", {2, 2}, "xy", 'B', i8, std::nullopt},
      {"scalar", {}, "", 'f', f32_bytes({42.0f}), std::nullopt},
  });
  testing::TempDir tmp;
  write_file(tmp / "small.tza", bytes);
  const nn::TzaFile f = nn::read_tza(tmp / "small.tza");
  ASSERT_EQ(f.tensors.size(), 5u);

  const auto& a = f.tensors.at("a.weight");
  EXPECT_EQ(a.shape, (std::vector<int64_t>{2, 2, 1, 2}));
  EXPECT_EQ(a.layout, "oihw");
  ASSERT_EQ(a.values.size(), f32.size());
  for (size_t i = 0; i < f32.size(); ++i)
    EXPECT_EQ(std::bit_cast<uint32_t>(a.values[i]), std::bit_cast<uint32_t>(f32[i])) << i;

  const auto& h = f.tensors.at("a.bias");
  EXPECT_EQ(h.shape, std::vector<int64_t>{12});
  EXPECT_EQ(h.layout, "x");
  ASSERT_EQ(h.values.size(), f16.size());
  for (size_t i = 0; i + 1 < f16.size(); ++i)
    EXPECT_EQ(std::bit_cast<uint32_t>(h.values[i]), std::bit_cast<uint32_t>(f16_expected[i])) << i;
  EXPECT_TRUE(std::isnan(h.values.back()));

  EXPECT_EQ(f.tensors.at("q.signed").values, (std::vector<float>{0.0f, 127.0f, -128.0f, -1.0f}));
  EXPECT_EQ(f.tensors.at("q.unsigned").values, (std::vector<float>{0.0f, 127.0f, 128.0f, 255.0f}));
  EXPECT_EQ(f.tensors.at("q.unsigned").layout, "xy");
  EXPECT_TRUE(f.tensors.at("scalar").shape.empty());
  EXPECT_EQ(f.tensors.at("scalar").values, std::vector<float>{42.0f});
}

TEST(Tza, Float16ConversionIsExactForEveryHalf) {
  std::vector<uint16_t> all(65536);
  for (uint32_t i = 0; i < 65536; ++i) all[i] = static_cast<uint16_t>(i);
  const auto bytes = build_tza({{"all", {65536}, "x", 'h', f16_bytes(all), std::nullopt}});
  const auto values = nn::parse_tza(bytes, "every half").tensors.at("all").values;
  ASSERT_EQ(values.size(), 65536u);
  for (uint32_t i = 0; i < 65536; ++i) {
    const float expected = static_cast<float>(Imath::half(Imath::half::FromBits, static_cast<uint16_t>(i)));
    if (std::isnan(expected)) {
      ASSERT_TRUE(std::isnan(values[i])) << std::hex << i;
      // The sign and payload survive: the float's top mantissa bits are the half's.
      EXPECT_EQ(std::bit_cast<uint32_t>(values[i]), ((i & 0x8000u) << 16) | 0x7F800000u | ((i & 0x3FFu) << 13))
          << std::hex << i;
    } else {
      ASSERT_EQ(std::bit_cast<uint32_t>(values[i]), std::bit_cast<uint32_t>(expected)) << std::hex << i;
    }
  }
}

// --- malformed files --------------------------------------------------------------------------------------------

TEST(Tza, RejectsBadMagicAndVersion) {
  auto bytes = build_tza({good_f32()});
  bytes[0] = 0x50;
  bytes[1] = 0x4B;
  expect_input_error(bytes, "magic.tza", {"bad magic 0x4B50", "0x41D7"});
  expect_input_error(build_tza({good_f32()}, 1, 0), "v1.tza", {"version 1.0", "expected version 2"});
  expect_input_error(build_tza({good_f32()}, 3, 1), "v3.tza", {"version 3.1", "expected version 2"});
}

TEST(Tza, RejectsTruncatedHeaderTableAndData) {
  const auto bytes = build_tza({good_f32("first.weight"), good_f32("second.weight")});
  expect_input_error({}, "empty.tza", {"truncated", "0 bytes"});
  expect_input_error(std::vector<uint8_t>(bytes.begin(), bytes.begin() + 7), "header.tza", {"truncated", "header"});
  // Cut at every point inside the table: each is reported as a truncated table, naming the tensor once its name
  // has been read.
  const uint64_t table = bytes[4] | (bytes[5] << 8);
  for (size_t cut = table; cut < bytes.size(); ++cut) {
    SCOPED_TRACE(cut);
    std::vector<uint8_t> cut_bytes(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(cut));
    const size_t second_name_end = bytes.size() - (8 + 1 + 4 + 4 * 4 + 1);  // after "second.weight"
    std::vector<std::string> parts = {"truncated", "tensor table"};
    if (cut >= second_name_end) parts.push_back("\"second.weight\"");
    expect_input_error(cut_bytes, "table.tza", parts);
  }
  // Data that runs past the end of the file: 16 bytes needed from 8 before the end (the offset does not change
  // the archive's size, so build once to learn it).
  auto spec = good_f32("late.weight");
  spec.offset = build_tza({spec}).size() - 8;
  const auto late = build_tza({spec});
  expect_input_error(late, "data.tza", {"truncated", "\"late.weight\"", "needs 16 bytes"});
}

TEST(Tza, RejectsOffsetsAndSizesOutOfRange) {
  // Table offset past the end, and inside the header.
  for (uint64_t table : {uint64_t{1} << 40, uint64_t{4}, std::numeric_limits<uint64_t>::max()}) {
    auto bytes = build_tza({good_f32()});
    for (int i = 0; i < 8; ++i) bytes[4 + i] = static_cast<uint8_t>(table >> (8 * i));
    expect_input_error(bytes, "table_offset.tza", {"table offset", "out of range"});
  }
  // Data offsets past the end, including ones where offset + size would wrap around 64 bits.
  for (uint64_t offset : {uint64_t{1} << 32, std::numeric_limits<uint64_t>::max() - 3}) {
    auto spec = good_f32("far.weight");
    spec.offset = offset;
    expect_input_error(build_tza({spec}), "data_offset.tza", {"\"far.weight\"", "past the end"});
  }
  // Shapes whose element count overflows 64 bits (2^32-1)^3 > 2^64, and one whose byte size does:
  // (2^32-1)^2 elements fit in 64 bits, 4 bytes each do not.
  expect_input_error(build_tza({{"huge.weight", {0xFFFFFFFFu, 0xFFFFFFFFu, 0xFFFFFFFFu}, "abc", 'f', {}, std::nullopt}}),
                     "numel.tza", {"\"huge.weight\"", "overflows 64 bits"});
  expect_input_error(build_tza({{"wide.weight", {0xFFFFFFFFu, 0xFFFFFFFFu}, "oi", 'f', {}, std::nullopt}}),
                     "bytes.tza", {"\"wide.weight\"", "overflows 64 bits"});
  // Large but representable: runs past the end of the file.
  expect_input_error(build_tza({{"big.weight", {65536, 65536}, "oi", 'h', {}, std::nullopt}}), "big.tza",
                     {"\"big.weight\"", "truncated", "8589934592 bytes"});
}

TEST(Tza, RejectsUnknownDtypeBadLayoutDuplicatesAndEmptyArchives) {
  auto spec = good_f32("odd.weight");
  spec.dtype = 'd';
  expect_input_error(build_tza({spec}), "dtype.tza", {"\"odd.weight\"", "unknown dtype 'd'", "'f'", "'h'"});
  spec.dtype = '\x01';
  expect_input_error(build_tza({spec}), "dtype1.tza", {"\"odd.weight\"", "unknown dtype byte 0x01"});

  auto layout = good_f32("short.weight");
  layout.layout = std::string("oi\0\0", 4);  // 2 letters for 4 dimensions
  expect_input_error(build_tza({layout}), "layout.tza", {"\"short.weight\"", "layout \"oi\"", "expected 4"});

  expect_input_error(build_tza({good_f32("twice.weight"), good_f32("other.bias"), good_f32("twice.weight")}),
                     "dup.tza", {"\"twice.weight\"", "twice"});

  expect_input_error(build_tza({}), "none.tza", {"no tensors"});
  // A count larger than the table really holds is a truncated table.
  expect_input_error(build_tza({good_f32()}, 2, 0, 2u), "count.tza", {"truncated", "tensor #2 of 2"});
}

TEST(Tza, ParseNamesTheGivenSourceAndReadNamesMissingFiles) {
  try {
    nn::parse_tza({1, 2, 3}, "buffer from somewhere");
    ADD_FAILURE() << "no throw";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Input);
    EXPECT_NE(std::string(e.what()).find("buffer from somewhere"), std::string::npos) << e.what();
  }
  try {
    nn::read_tza("/nonexistent/nothing.tza");
    ADD_FAILURE() << "no throw";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Input);
    EXPECT_NE(std::string(e.what()).find("nothing.tza"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace residue
