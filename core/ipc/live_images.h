// Images streamed by a renderer over tev's protocol, assembled as they arrive, and turned into AOV stacks.
//
// A client creates an image (size and channel names), then sends rectangles of some of its channels, usually
// 128x128 tiles, as it renders. Channel names are recognised as in a file ("R,G,B", "albedo.R", "N.X", ...), so
// a renderer that streams its AOVs beside the beauty gets them used as guides.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/aov/aov_stack.h"
#include "core/image/image.h"
#include "core/ipc/tev_protocol.h"

namespace residue::ipc {

struct LiveImage {
  std::vector<std::string> channel_names;
  Image pixels;           // one channel per name, 0 until sent
  uint64_t updates = 0;   // update packets applied
};

class LiveImages {
 public:
  // `max_bytes`: what all live images may hold together, whatever the number of clients (0: no cap).
  explicit LiveImages(size_t max_bytes = 0) : max_bytes_(max_bytes) {}
  // Creates (or re-creates, as tev does) an image. Throws Error(Input) naming it, its size and the cap, and
  // keeps what was there, when it would take the images past max_bytes.
  void apply(const CreateImage& packet);
  // Writes a rectangle into an existing image and returns the part of it inside the image (empty when none).
  // Throws Error(Input) naming the image or the channel when either does not exist.
  Rect apply(const UpdateImage& packet);
  bool close(const std::string& name);  // false when there was no such image

  const LiveImage* find(const std::string& name) const;
  size_t size() const { return images_.size(); }
  size_t bytes() const;  // held by all live images now
  size_t max_bytes() const { return max_bytes_; }

 private:
  std::map<std::string, LiveImage> images_;
  size_t max_bytes_ = 0;
};

// The AOV stack of a live image: its channels recognised by name (root R,G,B is the colour). Throws Error(Input)
// naming the image and its channels when no colour is among them.
AovStack live_aov_stack(const std::string& name, const LiveImage& image);

}  // namespace residue::ipc
