#include "core/aov/read_plan.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>

#include "core/aov/exr_header_check.h"
#include "core/util/error.h"
#include "core/util/input_file.h"

namespace residue {
namespace fs = std::filesystem;
namespace {

bool decodes_srgb(const OIIO::ImageSpec& spec, AovRole role) {
  return encoded_srgb(spec) && (role == AovRole::Color || role == AovRole::Albedo || role == AovRole::Reference);
}

float srgb_to_linear(float v) {
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

}  // namespace

// Whether a file's values are display-encoded sRGB (a PNG or JPEG as most tools write them), which colour AOVs
// must be decoded from: light adds up only in linear values.
bool encoded_srgb(const OIIO::ImageSpec& spec) {
  std::string cs = spec.get_string_attribute("oiio:ColorSpace");
  std::transform(cs.begin(), cs.end(), cs.begin(), [](unsigned char c) { return std::tolower(c); });
  return cs.rfind("srgb", 0) == 0;
}

OpenedFile open_file(const fs::path& path) {
  check_input_file(path, "input");
  check_exr_header(path);  // before OpenEXR allocates what a corrupt header declares
  auto in = OIIO::ImageInput::open(path.string());
  if (!in)
    throw Error(ErrorKind::Input, "cannot read '" + path.string() + "': " + OIIO::geterror());
  // The format is what the bytes say: a PNG renamed .exr would otherwise be read as linear values.
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return std::tolower(c); });
  if (extension == ".exr" && std::string(in->format_name()) != "openexr")
    throw Error(ErrorKind::Input, "'" + path.string() + "' is named .exr but is a " + in->format_name() +
                                      " file, not OpenEXR (renamed?); AOVs are read from OpenEXR files");
  OpenedFile f;
  f.path = path.string();
  f.format = in->format_name();
  for (int sub = 0; in->seek_subimage(sub, 0); ++sub) {
    const OIIO::ImageSpec& spec = in->spec();
    if (spec.deep)
      throw Error(ErrorKind::Input, "'" + path.string() + "'" + (sub > 0 ? " part " + std::to_string(sub) : std::string()) +
                                        " is a deep image (several samples per pixel): deep images are not supported; "
                                        "flatten it first (oiiotool in.exr --flatten -o flat.exr)");
    f.specs.push_back(spec);
    // Parts of a multipart EXR may name channels without their layer ("R" in part "albedo"): qualify them.
    const std::string part = spec.get_string_attribute("name");
    for (int c = 0; c < spec.nchannels; ++c) {
      ChannelRef ref;
      ref.subimage = sub;
      ref.index = c;
      ref.name = spec.channelnames[static_cast<size_t>(c)];
      if (sub > 0 && !part.empty() && ref.name.find('.') == std::string::npos) ref.name = part + "." + ref.name;
      ref.pixel_type = spec.channelformat(c).c_str();
      f.channels.push_back(ref);
    }
  }
  if (f.specs.empty())
    throw Error(ErrorKind::Input, "'" + path.string() + "' holds no image");
  return f;
}

std::string channel_list(const OpenedFile& f, size_t max_names) {
  std::string s;
  for (size_t i = 0; i < f.channels.size() && i < max_names; ++i) s += (i ? ", " : "") + f.channels[i].name;
  if (f.channels.size() > max_names) s += ", ... (" + std::to_string(f.channels.size()) + " in all)";
  return s.empty() ? "(none)" : s;
}

std::string expected_text(AovRole role) {
  switch (role) {
    case AovRole::Color:
      return "a beauty pass: R,G,B, Combined.R/G/B (Cycles), Ci (RenderMan), or --map color=...";
    case AovRole::Albedo: return "3 channels, e.g. albedo.R/G/B or Denoising Albedo.R/G/B";
    case AovRole::Normal: return "3 channels, e.g. normal.X/Y/Z or Denoising Normal.X/Y/Z";
    case AovRole::Depth: return "1 channel, e.g. depth.Z, Z or Denoising Depth.Z";
    case AovRole::Variance: return "1 or 3 channels";
    case AovRole::Reference: return "3 channels (R,G,B)";
    case AovRole::Motion: return "4 channels, e.g. Vector.X/Y/Z/W (Cycles' Vector pass)";
  }
  return "";
}

ReadPlan whole_file_plan(AovRole role, const OpenedFile& f) {
  ReadPlan p;
  p.role = role;
  p.file = f.path;
  // A file whose naming says which channels are this AOV (a multilayer render given as --map albedo=FILE has
  // its "Denoising Albedo" layer): those, not its first channels (the beauty).
  const Recognition r = recognise_channels(f.channels);
  const AovRole named = role == AovRole::Reference ? AovRole::Color : role;
  if (const RecognisedAov* c = r.find(named)) {
    ReadPlan found = plan_from_recognition(*c, f.path);
    found.role = role;
    return found;
  }
  const int want = expected_channels(role);
  const std::vector<ChannelRef> first = [&] {
    std::vector<ChannelRef> v;
    for (const auto& c : f.channels)
      if (c.subimage == 0 && c.name != "A" && c.name != "a") v.push_back(c);
    return v;
  }();
  if (static_cast<int>(first.size()) >= want) {
    p.channels.assign(first.begin(), first.begin() + want);
  } else if (role == AovRole::Variance && first.size() == 1) {
    p.channels = first;
  } else {
    throw Error(ErrorKind::Input, "'" + f.path + "' should hold the " + to_string(role) + " AOV: expected " +
                                      expected_text(role) + "; found channels " + channel_list(f));
  }
  p.layer = "(whole file)";
  return p;
}

ReadPlan plan_from_recognition(const RecognisedAov& r, const std::string& file) {
  ReadPlan p;
  p.role = r.role;
  p.file = file;
  p.layer = r.layer;
  p.channels = r.channels;
  p.meaning = r.meaning;
  return p;
}

ReadPlan plan_from_binding(AovRole role, const ChannelBinding& b, const OpenedFile& f) {
  ReadPlan p;
  if (b.channels.empty()) {
    p = whole_file_plan(role, f);
  } else {
    p.role = role;
    p.file = f.path;
    if (b.channels.size() == 1 && expected_channels(role) > 1) {
      p.channels = find_layer_channels(f.channels, b.channels.front(), expected_channels(role));
      p.layer = b.channels.front();
      if (p.channels.empty())
        throw Error(ErrorKind::Mapping, "mapping for " + std::string(to_string(role)) + ": '" + f.path +
                                            "' has no layer \"" + b.channels.front() + "\" with " +
                                            std::to_string(expected_channels(role)) + " channels; found " +
                                            channel_list(f));
    } else {
      for (const auto& name : b.channels) {
        auto it = std::find_if(f.channels.begin(), f.channels.end(),
                               [&](const ChannelRef& c) { return c.name == name; });
        if (it == f.channels.end())
          throw Error(ErrorKind::Mapping, "mapping for " + std::string(to_string(role)) + ": channel \"" + name +
                                              "\" is not in '" + f.path + "'; found " + channel_list(f));
        p.channels.push_back(*it);
      }
      p.layer = "(mapped)";
    }
    const size_t n = p.channels.size();
    const bool ok = role == AovRole::Variance ? (n == 1 || n == 3) : n == static_cast<size_t>(expected_channels(role));
    if (!ok)
      throw Error(ErrorKind::Mapping, "mapping for " + std::string(to_string(role)) + " names " +
                                          std::to_string(n) + " channels; expected " + expected_text(role));
  }
  if (b.normal_space) p.meaning.normal_space = *b.normal_space;
  if (b.depth_background) p.depth_background = *b.depth_background;
  return p;
}

// Where a plan's AOV comes from.
AovSource describe(const ReadPlan& p) {
  AovSource src;
  src.file = p.file;
  src.subimage = p.channels.front().subimage;
  src.layer = p.layer;
  for (const auto& c : p.channels) {
    src.channels.push_back(c.name);
    src.pixel_types.push_back(c.pixel_type);
    if (c.subimage != src.subimage)
      throw Error(ErrorKind::Mapping, "the " + std::string(to_string(p.role)) + " channels of '" + p.file +
                                          "' come from different parts of the file");
  }
  return src;
}

// Reads every plan that uses `file` into `out[role]`, placing pixels on `grid` (display coordinates).
void read_plans(const OpenedFile& file, const std::vector<const ReadPlan*>& plans, const Rect& grid,
                std::map<AovRole, Aov>& out) {
  auto in = OIIO::ImageInput::open(file.path);
  if (!in) throw Error(ErrorKind::Input, "cannot read '" + file.path + "': " + OIIO::geterror());
  std::map<int, std::vector<const ReadPlan*>> by_subimage;
  for (const ReadPlan* p : plans) {
    Aov& aov = out[p->role];
    // Pixels a file's data window does not cover are 0, except in the reference: there they are NaN, so that
    // metrics exclude (and count) them instead of scoring against black.
    const float uncovered = p->role == AovRole::Reference ? std::numeric_limits<float>::quiet_NaN() : 0.0f;
    aov.image = Image(grid.width, grid.height, static_cast<int>(p->channels.size()), uncovered);
    aov.source = describe(*p);
    by_subimage[aov.source.subimage].push_back(p);
  }

  for (const auto& [sub, sub_plans] : by_subimage) {
    if (!in->seek_subimage(sub, 0))
      throw Error(ErrorKind::Input, "cannot read part " + std::to_string(sub) + " of '" + file.path + "'");
    const OIIO::ImageSpec& spec = in->spec();
    int ch_begin = spec.nchannels, ch_end = 0;
    for (const ReadPlan* p : sub_plans)
      for (const auto& c : p->channels) {
        ch_begin = std::min(ch_begin, c.index);
        ch_end = std::max(ch_end, c.index + 1);
      }
    const int nch = ch_end - ch_begin;
    // Rows and columns of the grid this part covers.
    const int64_t x0 = std::max<int64_t>(grid.x, spec.x), x1 = std::min<int64_t>(grid.x + grid.width, spec.x + spec.width);
    const int64_t y0 = std::max<int64_t>(grid.y, spec.y), y1 = std::min<int64_t>(grid.y + grid.height, spec.y + spec.height);
    const int64_t covered = std::max<int64_t>(0, x1 - x0) * std::max<int64_t>(0, y1 - y0);
    for (const ReadPlan* p : sub_plans) out[p->role].uncovered_pixels = grid.area() - covered;
    if (covered == 0) continue;

    // Read in bands of rows so memory stays bounded for huge images; tiled files read whole tile rows.
    const int64_t tile_h = spec.tile_height > 0 ? spec.tile_height : 0;
    const int64_t band = tile_h > 0 ? std::max<int64_t>(tile_h, (64 / tile_h) * tile_h) : 64;
    std::vector<float> buffer(static_cast<size_t>(band * spec.width * nch));
    int64_t y = tile_h > 0 ? spec.y + ((y0 - spec.y) / tile_h) * tile_h : y0;
    while (y < y1) {
      const int64_t y_end = std::min<int64_t>(y + band, spec.y + spec.height);
      bool ok = false;
      if (tile_h > 0)
        ok = in->read_tiles(sub, 0, spec.x, spec.x + spec.width, static_cast<int>(y), static_cast<int>(y_end), 0, 1,
                            ch_begin, ch_end, OIIO::TypeFloat, buffer.data());
      else
        ok = in->read_scanlines(sub, 0, static_cast<int>(y), static_cast<int>(y_end), 0, ch_begin, ch_end,
                                OIIO::TypeFloat, buffer.data());
      if (!ok)
        throw Error(ErrorKind::Input, "error reading rows " + std::to_string(y) + "-" + std::to_string(y_end) +
                                          " of '" + file.path + "': " + in->geterror());
      for (const ReadPlan* p : sub_plans) {
        Image& img = out[p->role].image;
        const int dst_ch = img.channels();
        const bool decode = decodes_srgb(spec, p->role);
        for (int64_t row = std::max(y, y0); row < std::min(y_end, y1); ++row) {
          const float* src = buffer.data() + (row - y) * spec.width * nch;
          for (int64_t x = x0; x < x1; ++x)
            for (int c = 0; c < dst_ch; ++c) {
              const float v = src[(x - spec.x) * nch + (p->channels[static_cast<size_t>(c)].index - ch_begin)];
              img.at(x - grid.x, row - grid.y, c) = decode ? srgb_to_linear(v) : v;
            }
        }
      }
      y = y_end;
    }
  }
}

}  // namespace residue
