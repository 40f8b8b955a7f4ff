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
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/aov/aov_loader.h"
#include "core/aov/channel_mapping.h"
#include "core/aov/exr_header_check.h"
#include "core/ipc/live_images.h"
#include "core/ipc/tev_protocol.h"
#include "core/nn/model_file.h"
#include "core/nn/oidn_network.h"
#include "core/nn/safetensors.h"
#include "core/nn/tza.h"
#include "core/util/error.h"
#include "tests/support/tev_packet.h"

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

// The most channel values any window or tile of the header declares, from the bytes alone
// (core/aov/exr_header_check.h): opening the file already allocates by them (OpenEXR 3.1 sizes a compressor's line
// buffer by the data window: found by fuzz_exr_loader), so this gate cannot ask OpenImageIO.
inline double exr_declared_values(const uint8_t* bytes, size_t size) {
  const ExrDeclaredPixels declared = exr_declared_pixels(bytes, size);
  double largest = 0;
  for (const auto* extent : {&declared.windows, &declared.display_windows, &declared.tiles})
    for (const auto& [width, height] : *extent) largest = std::max(largest, width * height);
  return largest * std::max(declared.channels, 1.0);
}

// OpenEXR 3.1 allocates what a header declares before reading it; the loader refuses such headers first
// (core/aov/exr_header_check.h), but exr_small_enough below opens the file before the loader, so it checks too.
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
  if (exr_header_problem(data, size, size)) return;
  if (exr_declared_values(data, size) > static_cast<double>(kMaxExrValues)) return;
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

// fuzz_tev_ipc: the bytes as a TCP stream from a tev client, fed to the packet stream in pieces whose size the
// first byte chooses (so that packets straddle reads), every framed packet decoded; the whole input also as one
// packet. What the viewer's IPC server does with each connection, without the socket.
inline void tev_ipc_one(const uint8_t* data, size_t size) {
  try {
    (void)ipc::parse_tev_packet({data, size});
  } catch (const std::exception&) {
  }
  if (size == 0) return;
  const size_t piece = size_t{data[0]} + 1;
  ipc::TevLimits limits;
  limits.max_packet_bytes = 1u << 20;  // small inputs; keeps a declared 512 MiB packet from being awaited
  ipc::TevPacketStream stream(limits);
  try {
    for (size_t pos = 1; pos < size; pos += piece) {
      stream.feed({data + pos, std::min(piece, size - pos)});
      while (auto packet = stream.next()) {
        try {
          (void)ipc::parse_tev_packet(*packet, limits);
        } catch (const std::exception&) {
        }
      }
    }
  } catch (const std::exception&) {
    // a length field out of range: the server closes the connection
  }
}

// fuzz_live_images: the state behind the viewer's IPC server, not only its parser. The bytes are a script of
// operations by up to three clients on four image names: create (any size up to 96x96, or now and then one far
// beyond the images' memory cap), update a rectangle (partly outside the image, of channels it may not have),
// close, corrupt the next packet, and "show" (turn an image into an AOV stack, as the window does, and read
// it where the canvas would). Each packet goes through the client's byte stream, the decoder and the live
// images, as in TevServer; a client whose packet is refused is disconnected (its stream reset) and the others
// go on. Checked on every step: what was last written to a pixel is what the stack shows, the live images never
// hold more than their cap, and an image that was refused or closed is not there.
class LiveImagesScript {
 public:
  LiveImagesScript(const uint8_t* data, size_t size) : data_(data), size_(size) {}

  void run() {
    while (pos_ < size_) {
      const uint8_t op = next();
      const size_t client = next() % kClients;
      const std::string name = std::string("img") + static_cast<char>('0' + next() % 4);
      switch (op % 6) {
        case 0: create(client, name); break;
        case 1:
        case 2: update(client, name); break;
        case 3: send(client, testing::TevPacket(2).str(name).done()); break;
        case 4: corrupt_next_ = true; break;
        case 5: show(name); break;
      }
    }
    for (const char* n : {"img0", "img1", "img2", "img3"}) show(n);
  }

 private:
  static constexpr size_t kClients = 3;
  static constexpr size_t kCap = 96 * 96 * 4 * 4 * 2;  // two full-size RGBA images

  uint8_t next() { return pos_ < size_ ? data_[pos_++] : 0; }

  void create(size_t client, const std::string& name) {
    const bool huge = next() == 255;
    const int32_t w = huge ? 16384 : 1 + next() % 96, h = huge ? 16384 : 1 + next() % 96;
    static const std::vector<std::vector<std::string>> kLayouts = {
        {"R", "G", "B"}, {"R", "G", "B", "A"}, {"R", "G", "B", "albedo.R", "albedo.G", "albedo.B"}, {"Y"}, {"N.X", "N.Y", "N.Z"}};
    const auto& channels = kLayouts[next() % kLayouts.size()];
    testing::TevPacket p(4);
    p.u8(1).str(name).i32(w).i32(h).i32(static_cast<int32_t>(channels.size()));
    for (const auto& c : channels) p.str(c);
    send(client, p.done());
  }

  void update(size_t client, const std::string& name) {
    static const std::vector<std::string> kChannels = {"R", "G", "B", "A", "albedo.G", "Z"};
    const std::string channel = kChannels[next() % kChannels.size()];
    const int32_t x = next() % 100, y = next() % 100, w = 1 + next() % 40, h = 1 + next() % 40;
    const float base = static_cast<float>(next());
    testing::TevPacket p(3);
    p.u8(0).str(name).str(channel).i32(x).i32(y).i32(w).i32(h);
    for (int32_t i = 0; i < w * h; ++i) p.f32(base + static_cast<float>(i));
    send(client, p.done());
  }

  // One packet over one client's connection, handled as TevServer does.
  void send(size_t client, std::vector<uint8_t> bytes) {
    if (corrupt_next_ && bytes.size() > 5) bytes[5 + next() % (bytes.size() - 5)] ^= static_cast<uint8_t>(1 + next() % 255);
    corrupt_next_ = false;
    try {
      streams_[client].feed({bytes.data(), bytes.size()});
      while (auto packet = streams_[client].next()) apply(ipc::parse_tev_packet(*packet, limits()));
    } catch (const std::exception&) {
      streams_[client] = ipc::TevPacketStream(limits());  // the server drops this client; it reconnects
    }
    if (images_.bytes() > kCap) std::abort();
  }

  void apply(const ipc::TevPacket& packet) {
    if (const auto* create = std::get_if<ipc::CreateImage>(&packet)) {
      images_.apply(*create);  // throws when over the cap: then the shadow keeps what was there
      shadow_[create->name] = {create->width, create->height, create->channel_names,
                               std::vector<float>(static_cast<size_t>(create->width) * create->height *
                                                      create->channel_names.size(), 0.0f)};
    } else if (const auto* u = std::get_if<ipc::UpdateImage>(&packet)) {
      const Rect r = images_.apply(*u);
      Shadow& s = shadow_.at(u->name);
      for (size_t k = 0; k < u->channel_names.size(); ++k) {
        const auto c = static_cast<size_t>(std::find(s.channels.begin(), s.channels.end(), u->channel_names[k]) - s.channels.begin());
        for (int64_t y = r.y; y < r.y + r.height; ++y)
          for (int64_t x = r.x; x < r.x + r.width; ++x)
            s.values[(static_cast<size_t>(y) * s.width + x) * s.channels.size() + c] =
                u->planes[k][static_cast<size_t>((y - u->y) * u->width + (x - u->x))];
      }
    } else if (const auto* closed = std::get_if<ipc::CloseImage>(&packet)) {
      images_.close(closed->name);
      shadow_.erase(closed->name);
    }
  }

  // What the window does with an image it shows: an AOV stack, read where the canvas reads its values.
  void show(const std::string& name) {
    const ipc::LiveImage* live = images_.find(name);
    if ((live == nullptr) != (shadow_.count(name) == 0)) std::abort();
    if (!live) return;
    try {
      const AovStack stack = ipc::live_aov_stack(name, *live);
      const Shadow& s = shadow_.at(name);
      if (stack.width() != s.width || stack.height() != s.height) std::abort();
      const size_t r = static_cast<size_t>(std::find(s.channels.begin(), s.channels.end(), "R") - s.channels.begin());
      for (int64_t y : {int64_t{0}, int64_t{s.height} - 1})
        for (int64_t x : {int64_t{0}, int64_t{s.width} - 1})
          if (r < s.channels.size() &&
              stack.color.image.at(x, y, 0) != s.values[(static_cast<size_t>(y) * s.width + x) * s.channels.size() + r])
            std::abort();
    } catch (const Error&) {
      // no colour among its channels: the window says so and keeps what it showed
    }
  }

  static ipc::TevLimits limits() {
    ipc::TevLimits l;
    l.max_packet_bytes = 1u << 20;
    return l;
  }

  struct Shadow {
    int32_t width = 0, height = 0;
    std::vector<std::string> channels;
    std::vector<float> values;
  };
  const uint8_t* data_;
  size_t size_, pos_ = 0;
  bool corrupt_next_ = false;
  ipc::LiveImages images_{kCap};
  std::vector<ipc::TevPacketStream> streams_ = std::vector<ipc::TevPacketStream>(kClients, ipc::TevPacketStream(limits()));
  std::map<std::string, Shadow> shadow_;
};

inline void live_images_one(const uint8_t* data, size_t size) { LiveImagesScript(data, size).run(); }

}  // namespace residue::fuzz
