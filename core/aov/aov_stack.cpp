#include "core/aov/aov_stack.h"

#include <algorithm>
#include <cctype>

namespace residue {
namespace {
std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}
}  // namespace

const char* to_string(AovRole role) {
  switch (role) {
    case AovRole::Color: return "color";
    case AovRole::Albedo: return "albedo";
    case AovRole::Normal: return "normal";
    case AovRole::Depth: return "depth";
    case AovRole::Variance: return "variance";
    case AovRole::Reference: return "reference";
    case AovRole::Motion: return "motion";
  }
  return "?";
}

std::optional<AovRole> aov_role_from_string(const std::string& name) {
  const std::string n = lower(name);
  for (AovRole r : kAllAovRoles)
    if (n == to_string(r)) return r;
  if (n == "colour" || n == "beauty") return AovRole::Color;
  return std::nullopt;
}

int expected_channels(AovRole role) {
  switch (role) {
    case AovRole::Depth: return 1;
    case AovRole::Motion: return 4;
    default: return 3;
  }
}

const char* to_string(NormalSpace space) {
  switch (space) {
    case NormalSpace::Camera: return "camera";
    case NormalSpace::World: return "world";
    case NormalSpace::Unknown: return "unknown";
  }
  return "?";
}

std::optional<NormalSpace> normal_space_from_string(const std::string& name) {
  const std::string n = lower(name);
  if (n == "camera" || n == "view") return NormalSpace::Camera;
  if (n == "world") return NormalSpace::World;
  if (n == "unknown") return NormalSpace::Unknown;
  return std::nullopt;
}

const char* to_string(DepthKind kind) {
  switch (kind) {
    case DepthKind::Planar: return "planar (distance along the view axis)";
    case DepthKind::RayLength: return "ray length (distance along the camera ray)";
    case DepthKind::Unknown: return "unknown definition";
  }
  return "?";
}

int64_t AovStack::channel_count() const {
  int64_t n = 0;
  for (AovRole role : kAllAovRoles)
    if (const Aov* a = find(role)) n += static_cast<int64_t>(a->source.channels.size());
  return n;
}

std::vector<int> neighbour_offsets(int radius) {
  std::vector<int> offsets;
  for (int d = -radius; d <= radius; ++d)
    if (d != 0) offsets.push_back(d);
  return offsets;
}

const WarpedNeighbour* AovStack::neighbour(int offset) const {
  for (const WarpedNeighbour& n : neighbours)
    if (n.offset == offset) return &n;
  return nullptr;
}

const Aov* AovStack::find(AovRole role) const { return const_cast<AovStack*>(this)->find(role); }

namespace {

// The optional member of a role; null for the colour, which is always there.
std::optional<Aov>* optional_slot(AovStack& s, AovRole role) {
  switch (role) {
    case AovRole::Color: return nullptr;
    case AovRole::Albedo: return &s.albedo;
    case AovRole::Normal: return &s.normal;
    case AovRole::Depth: return &s.depth;
    case AovRole::Variance: return &s.variance;
    case AovRole::Reference: return &s.reference;
    case AovRole::Motion: return &s.motion;
  }
  return nullptr;
}

}  // namespace

Aov* AovStack::find(AovRole role) {
  if (role == AovRole::Color) return &color;
  std::optional<Aov>* slot = optional_slot(*this, role);
  return slot && *slot ? &**slot : nullptr;
}

Aov& AovStack::emplace(AovRole role) {
  if (role == AovRole::Color) return color;
  std::optional<Aov>& slot = *optional_slot(*this, role);
  if (!slot) slot.emplace();
  return *slot;
}

}  // namespace residue
