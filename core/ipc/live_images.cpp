#include "core/ipc/live_images.h"

#include <algorithm>

#include "core/aov/aov_loader.h"
#include "core/aov/channel_naming.h"
#include "core/util/error.h"

namespace residue::ipc {

namespace {

size_t image_bytes(int64_t width, int64_t height, size_t channels) {
  return static_cast<size_t>(width) * static_cast<size_t>(height) * channels * sizeof(float);
}

std::string mib(size_t bytes) { return std::to_string((bytes + (size_t{1} << 20) - 1) >> 20) + " MiB"; }

}  // namespace

size_t LiveImages::bytes() const {
  size_t total = 0;
  for (const auto& [name, image] : images_) total += image.pixels.size() * sizeof(float);
  return total;
}

void LiveImages::apply(const CreateImage& packet) {
  const size_t wanted = image_bytes(packet.width, packet.height, packet.channel_names.size());
  const auto old = images_.find(packet.name);
  const size_t freed = old == images_.end() ? 0 : old->second.pixels.size() * sizeof(float);
  const size_t held = bytes() - freed;
  if (max_bytes_ > 0 && wanted > max_bytes_ - std::min(held, max_bytes_))
    throw Error(ErrorKind::Input, "tev IPC image '" + packet.name + "' (" + std::to_string(packet.width) + " x " +
                                      std::to_string(packet.height) + ", " + std::to_string(packet.channel_names.size()) +
                                      " channels) needs " + mib(wanted) + "; the streamed images may hold " +
                                      mib(max_bytes_) + " in all and hold " + mib(held) +
                                      " (close some, or raise the viewer's --ipc-memory)");
  LiveImage& image = images_[packet.name];
  image.channel_names = packet.channel_names;
  image.pixels = Image(packet.width, packet.height, static_cast<int>(packet.channel_names.size()));
  image.updates = 0;
}

Rect LiveImages::apply(const UpdateImage& packet) {
  auto it = images_.find(packet.name);
  if (it == images_.end())
    throw Error(ErrorKind::Input, "tev IPC update of image '" + packet.name + "', which was not created");
  LiveImage& image = it->second;
  std::vector<int> columns;
  for (const std::string& channel : packet.channel_names) {
    const auto c = std::find(image.channel_names.begin(), image.channel_names.end(), channel);
    if (c == image.channel_names.end()) {
      std::string have;
      for (const auto& n : image.channel_names) have += (have.empty() ? "" : ", ") + n;
      throw Error(ErrorKind::Input, "tev IPC update of image '" + packet.name + "': it has no channel '" + channel +
                                        "' (it has " + have + ")");
    }
    columns.push_back(static_cast<int>(c - image.channel_names.begin()));
  }
  // The part of the rectangle inside the image (a client may send a tile that overhangs).
  const Rect sent{packet.x, packet.y, packet.width, packet.height};
  const int64_t x0 = sent.x, y0 = sent.y;
  const int64_t x1 = std::min(sent.x + sent.width, image.pixels.width());
  const int64_t y1 = std::min(sent.y + sent.height, image.pixels.height());
  if (x1 <= x0 || y1 <= y0) return {};
  for (size_t c = 0; c < columns.size(); ++c) {
    const std::vector<float>& plane = packet.planes[c];
    for (int64_t y = y0; y < y1; ++y)
      for (int64_t x = x0; x < x1; ++x)
        image.pixels.at(x, y, columns[c]) = plane[static_cast<size_t>((y - y0) * sent.width + (x - x0))];
  }
  ++image.updates;
  return {x0, y0, x1 - x0, y1 - y0};
}

bool LiveImages::close(const std::string& name) { return images_.erase(name) > 0; }

const LiveImage* LiveImages::find(const std::string& name) const {
  auto it = images_.find(name);
  return it == images_.end() ? nullptr : &it->second;
}

AovStack live_aov_stack(const std::string& name, const LiveImage& image) {
  std::vector<ChannelRef> refs;
  for (size_t i = 0; i < image.channel_names.size(); ++i)
    refs.push_back({0, static_cast<int>(i), image.channel_names[i], "float"});
  const Recognition rec = recognise_channels(refs);
  if (!rec.find(AovRole::Color)) {
    std::string have;
    for (const auto& n : image.channel_names) have += (have.empty() ? "" : ", ") + n;
    throw Error(ErrorKind::Input, "streamed image '" + name + "' has no colour channels (it has " + have +
                                      "); expected R,G,B");
  }
  AovStack stack;
  stack.convention = "tev IPC stream, " + rec.convention;
  stack.notes = rec.notes;
  stack.data_window = image.pixels.bounds();
  stack.display_width = image.pixels.width();
  stack.display_height = image.pixels.height();
  for (const RecognisedAov& r : rec.aovs) {
    Aov& aov = stack.emplace(r.role);
    aov.image = Image(image.pixels.width(), image.pixels.height(), static_cast<int>(r.channels.size()));
    for (int64_t y = 0; y < image.pixels.height(); ++y)
      for (int64_t x = 0; x < image.pixels.width(); ++x)
        for (size_t c = 0; c < r.channels.size(); ++c)
          aov.image.at(x, y, static_cast<int>(c)) = image.pixels.at(x, y, r.channels[c].index);
    aov.source.file = "tev IPC: " + name;
    aov.source.layer = r.layer;
    for (const ChannelRef& ch : r.channels) {
      aov.source.channels.push_back(ch.name);
      aov.source.pixel_types.push_back("float");
    }
    stack.depth_background_pixels += normalise_aov(r.role, r.meaning.flip_normal_z, kDepthBackgroundThreshold, aov);
    if (r.role == AovRole::Normal) stack.normal_space = r.meaning.normal_space;
    if (r.role == AovRole::Depth) stack.depth_kind = r.meaning.depth_kind;
  }
  return stack;
}

}  // namespace residue::ipc
