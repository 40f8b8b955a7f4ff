// tev's IPC protocol (core/ipc/tev_protocol.h): packets as a tev client writes them, built byte by byte by the
// tests' own encoder (support/tev_packet.h), decoded and compared field by field; the
// stream framer fed in pieces; malformed packets refused with the field named.
#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "core/ipc/live_images.h"
#include "core/ipc/tev_protocol.h"
#include "core/util/error.h"
#include "support/tev_packet.h"

namespace residue::ipc {
namespace {

using Packet = residue::testing::TevPacket;

std::string error_of(const std::vector<uint8_t>& packet, const TevLimits& limits = {}) {
  try {
    (void)parse_tev_packet(packet, limits);
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Input);
    return e.what();
  }
  ADD_FAILURE() << "expected an Error";
  return "";
}

TEST(TevProtocol, OpenImageV1SplitsTheChannelSelectorButNotADriveLetter) {
  auto a = std::get<OpenImage>(parse_tev_packet(Packet(0).u8(1).str("/r/shot.exr:albedo.*").done()));
  EXPECT_TRUE(a.grab_focus);
  EXPECT_EQ(a.path, "/r/shot.exr");
  EXPECT_EQ(a.channel_selector, "albedo.*");
  auto b = std::get<OpenImage>(parse_tev_packet(Packet(0).u8(0).str("C:/r/shot.exr").done()));
  EXPECT_FALSE(b.grab_focus);
  EXPECT_EQ(b.path, "C:/r/shot.exr");
  EXPECT_EQ(b.channel_selector, "");
  auto c = std::get<OpenImage>(parse_tev_packet(Packet(7).u8(1).str("a:b.exr").str("R,G").done()));
  EXPECT_EQ(c.path, "a:b.exr");  // v2: the path is taken whole
  EXPECT_EQ(c.channel_selector, "R,G");
}

TEST(TevProtocol, ReloadCloseAndCreate) {
  auto r = std::get<ReloadImage>(parse_tev_packet(Packet(1).u8(0).str("beauty").done()));
  EXPECT_EQ(r.name, "beauty");
  EXPECT_FALSE(r.grab_focus);
  EXPECT_EQ(std::get<CloseImage>(parse_tev_packet(Packet(2).str("beauty").done())).name, "beauty");
  auto c = std::get<CreateImage>(
      parse_tev_packet(Packet(4).u8(1).str("live").i32(320).i32(200).i32(4).str("R").str("G").str("B").str("A").done()));
  EXPECT_EQ(c.name, "live");
  EXPECT_EQ(c.width, 320);
  EXPECT_EQ(c.height, 200);
  EXPECT_EQ(c.channel_names, (std::vector<std::string>{"R", "G", "B", "A"}));
}

TEST(TevProtocol, UpdateImageV1V2AndV3GiveTheSamePlanes) {
  const int w = 3, h = 2;
  auto value = [](int c, int p) { return 10.0f * static_cast<float>(c) + 0.5f * static_cast<float>(p); };
  // v1: one channel.
  Packet v1(3);
  v1.u8(0).str("img").str("G").i32(5).i32(7).i32(w).i32(h);
  for (int p = 0; p < w * h; ++p) v1.f32(value(1, p));
  auto u1 = std::get<UpdateImage>(parse_tev_packet(v1.done()));
  EXPECT_EQ(u1.channel_names, std::vector<std::string>{"G"});
  EXPECT_EQ(u1.x, 5);
  EXPECT_EQ(u1.y, 7);
  ASSERT_EQ(u1.planes.size(), 1u);
  for (int p = 0; p < w * h; ++p) EXPECT_EQ(u1.planes[0][static_cast<size_t>(p)], value(1, p));
  // v2: planar.
  Packet v2(5);
  v2.u8(1).str("img").i32(3).str("R").str("G").str("B").i32(0).i32(0).i32(w).i32(h);
  for (int c = 0; c < 3; ++c)
    for (int p = 0; p < w * h; ++p) v2.f32(value(c, p));
  // v3: interleaved RGBA with the alpha skipped (offsets 0,1,2 and stride 4), as a renderer's framebuffer.
  Packet v3(6);
  v3.u8(0).str("img").i32(3).str("R").str("G").str("B").i32(0).i32(0).i32(w).i32(h);
  for (int64_t c = 0; c < 3; ++c) v3.i64(c);
  for (int c = 0; c < 3; ++c) v3.i64(4);
  for (int p = 0; p < w * h; ++p) {
    for (int c = 0; c < 3; ++c) v3.f32(value(c, p));
    v3.f32(-1.0f);
  }
  for (const auto& bytes : {v2.done(), v3.done()}) {
    auto u = std::get<UpdateImage>(parse_tev_packet(bytes));
    EXPECT_EQ(u.width, w);
    EXPECT_EQ(u.height, h);
    ASSERT_EQ(u.planes.size(), 3u);
    for (int c = 0; c < 3; ++c)
      for (int p = 0; p < w * h; ++p)
        EXPECT_EQ(u.planes[static_cast<size_t>(c)][static_cast<size_t>(p)], value(c, p)) << "channel " << c;
  }
}

TEST(TevProtocol, StreamFramesPacketsWhateverTheReadSizes) {
  std::vector<uint8_t> stream;
  const std::vector<std::vector<uint8_t>> packets = {
      Packet(4).u8(1).str("live").i32(2).i32(1).i32(1).str("Y").done(),
      Packet(3).u8(0).str("live").str("Y").i32(0).i32(0).i32(2).i32(1).f32(1.5f).f32(2.5f).done(),
      Packet(2).str("live").done()};
  for (const auto& p : packets) stream.insert(stream.end(), p.begin(), p.end());
  for (size_t piece : {size_t{1}, size_t{3}, size_t{7}, stream.size()}) {
    TevPacketStream framer;
    std::vector<std::vector<uint8_t>> got;
    for (size_t pos = 0; pos < stream.size(); pos += piece) {
      framer.feed({stream.data() + pos, std::min(piece, stream.size() - pos)});
      while (auto p = framer.next()) got.push_back(*p);
    }
    EXPECT_EQ(got, packets) << "pieces of " << piece;
    EXPECT_EQ(framer.buffered(), 0u);
  }
  auto u = std::get<UpdateImage>(parse_tev_packet(packets[1]));
  EXPECT_EQ(u.planes[0], (std::vector<float>{1.5f, 2.5f}));
}

TEST(TevProtocol, MalformedPacketsAreRefusedNamingWhatIsWrong) {
  // Wrong length, unknown type, a string without its end, a truncated field.
  EXPECT_NE(error_of(Packet(2).str("x").done(99)).find("length field says 99 bytes, but it has 7"), std::string::npos);
  EXPECT_NE(error_of(Packet(9).str("x").done()).find("unknown type 9"), std::string::npos);
  auto unterminated = Packet(2).done();
  unterminated.push_back('a');
  unterminated[0] = static_cast<uint8_t>(unterminated.size());
  EXPECT_NE(error_of(unterminated).find("image name string has no terminating NUL"), std::string::npos);
  EXPECT_NE(error_of(Packet(4).u8(1).str("n").i32(4).done()).find("ends inside the height field"), std::string::npos);
  // Sizes: negative, zero, huge, too many channels.
  EXPECT_NE(error_of(Packet(4).u8(1).str("n").i32(-4).i32(4).i32(3).done()).find("width is -4"), std::string::npos);
  EXPECT_NE(error_of(Packet(4).u8(1).str("n").i32(65536).i32(65536).i32(4).done()).find("more than 1073741824 values"),
            std::string::npos);
  EXPECT_NE(error_of(Packet(5).u8(1).str("n").i32(5000).done()).find("channel count is 5000; expected 1 to 1024"),
            std::string::npos);
  // An update whose data is too short for its region, one with a negative stride, one whose stride of 0 would
  // decode a 2^31-pixel region from 4 bytes, one whose region overflows.
  Packet short_data(5);
  short_data.u8(0).str("n").i32(2).str("R").str("G").i32(0).i32(0).i32(4).i32(4);
  for (int i = 0; i < 31; ++i) short_data.f32(1.0f);
  EXPECT_NE(error_of(short_data.done()).find("the data holds 31 floats, too few for 4x4 pixels of channel 'G'"),
            std::string::npos);
  auto v3 = [](int32_t w, int32_t h, int64_t offset, int64_t stride) {
    Packet p(6);
    p.u8(0).str("n").i32(1).str("R").i32(0).i32(0).i32(w).i32(h).i64(offset).i64(stride).f32(1.0f).f32(2.0f);
    return p.done();
  };
  EXPECT_NE(error_of(v3(2, 1, 0, -1)).find("offset 0 and stride -1"), std::string::npos);
  EXPECT_NE(error_of(v3(2, 1, 2, 1)).find("at offset 2, stride 1"), std::string::npos);
  EXPECT_NE(error_of(v3(65536, 32768, 0, 0)).find("more than 536870912 bytes of floats"), std::string::npos);
  EXPECT_NO_THROW((void)parse_tev_packet(v3(2, 1, 0, 1)));
  EXPECT_NO_THROW((void)parse_tev_packet(v3(4, 4, 1, 0)));  // stride 0: one value for every pixel
  Packet overflow(3);
  overflow.u8(0).str("n").str("R").i32(2147483647).i32(0).i32(1).i32(1).f32(0.0f);
  EXPECT_NE(error_of(overflow.done()).find("ends beyond 2^31 - 1"), std::string::npos);
  EXPECT_NE(error_of(Packet(8).u8(0).str("n").done()).find("vector graphics overlays are not supported"),
            std::string::npos);
  // The packet limit, and a stream whose length field is out of range.
  TevLimits small;
  small.max_packet_bytes = 16;
  EXPECT_NE(error_of(Packet(2).str("a long image name").done(), small).find("more than the limit of 16"),
            std::string::npos);
  for (uint32_t declared : {0u, 4u, 0xffffffffu}) {
    TevPacketStream framer;
    const uint8_t bytes[4] = {static_cast<uint8_t>(declared), static_cast<uint8_t>(declared >> 8),
                              static_cast<uint8_t>(declared >> 16), static_cast<uint8_t>(declared >> 24)};
    framer.feed(bytes);
    try {
      (void)framer.next();
      ADD_FAILURE() << "expected an Error for a declared length of " << declared;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("declares " + std::to_string(declared) + " bytes"), std::string::npos)
          << e.what();
    }
  }
}

// A renderer streaming a 5x3 image with albedo in 2x2 tiles, one overhanging the right edge: the assembled
// stack holds every value sent, in the right role.
TEST(LiveImages, TilesAssembleIntoAnAovStack) {
  LiveImages images;
  images.apply(std::get<CreateImage>(parse_tev_packet(Packet(4).u8(1).str("live").i32(5).i32(3).i32(6)
      .str("R").str("G").str("B").str("albedo.R").str("albedo.G").str("albedo.B").done())));
  auto value = [](int c, int x, int y) { return static_cast<float>(100 * c + 10 * y + x); };
  for (int ty = 0; ty < 3; ty += 2)
    for (int tx = 0; tx < 5; tx += 2) {
      const int w = 2, h = std::min(2, 3 - ty);  // the last column of tiles overhangs x = 5
      Packet p(5);
      p.u8(0).str("live").i32(6);
      for (const char* n : {"R", "G", "B", "albedo.R", "albedo.G", "albedo.B"}) p.str(n);
      p.i32(tx).i32(ty).i32(w).i32(h);
      for (int c = 0; c < 6; ++c)
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) p.f32(value(c, tx + x, ty + y));
      const Rect r = images.apply(std::get<UpdateImage>(parse_tev_packet(p.done())));
      EXPECT_EQ(r.width, tx == 4 ? 1 : 2);
    }
  const LiveImage* live = images.find("live");
  ASSERT_NE(live, nullptr);
  EXPECT_EQ(live->updates, 6u);
  const AovStack stack = live_aov_stack("live", *live);
  ASSERT_TRUE(stack.albedo);
  EXPECT_EQ(stack.width(), 5);
  EXPECT_EQ(stack.height(), 3);
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 5; ++x)
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(stack.color.image.at(x, y, c), value(c, x, y));
        EXPECT_EQ(stack.albedo->image.at(x, y, c), value(3 + c, x, y));
      }
  EXPECT_EQ(stack.albedo->source.file, "tev IPC: live");
  EXPECT_TRUE(images.close("live"));
  EXPECT_EQ(images.find("live"), nullptr);
}

// A stream of R,G,B with albedo.* and N.* is named by what it is, a plain stream (issue 53, item 14): "N" is
// Arnold's name for its normal but anyone's too; Arnold's streams are known by denoise_albedo or N with Z.
TEST(LiveImages, AStreamWithAlbedoAndNIsPlainNotArnold) {
  const auto convention = [](const std::vector<std::string>& channels) {
    LiveImages images;
    Packet create(4);
    create.u8(1).str("live").i32(2).i32(2).i32(static_cast<int>(channels.size()));
    for (const auto& c : channels) create.str(c);
    images.apply(std::get<CreateImage>(parse_tev_packet(create.done())));
    return live_aov_stack("live", *images.find("live")).convention;
  };
  EXPECT_EQ(convention({"R", "G", "B", "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z"}),
            "tev IPC stream, plain R,G,B with named layers");
  EXPECT_EQ(convention({"R", "G", "B", "denoise_albedo.R", "denoise_albedo.G", "denoise_albedo.B", "N.X", "N.Y", "N.Z"}),
            "tev IPC stream, Arnold");
  EXPECT_EQ(convention({"R", "G", "B", "N.X", "N.Y", "N.Z", "Z"}), "tev IPC stream, Arnold");
}

TEST(LiveImages, UpdatesOfUnknownImagesOrChannelsAndImagesWithoutColourAreRefused) {
  LiveImages images;
  UpdateImage u;
  u.name = "nope";
  u.channel_names = {"R"};
  u.width = u.height = 1;
  u.planes = {{1.0f}};
  EXPECT_THROW(images.apply(u), Error);
  CreateImage c;
  c.name = "depth only";
  c.width = c.height = 2;
  c.channel_names = {"Z"};
  images.apply(c);
  u.name = "depth only";
  try {
    images.apply(u);
    ADD_FAILURE() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("has no channel 'R' (it has Z)"), std::string::npos) << e.what();
  }
  try {
    (void)live_aov_stack("depth only", *images.find("depth only"));
    ADD_FAILURE() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'depth only' has no colour channels (it has Z)"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace residue::ipc
