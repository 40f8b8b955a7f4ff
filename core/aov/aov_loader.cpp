#include "core/aov/aov_loader.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>
#include <nlohmann/json.hpp>

#include "core/aov/channel_naming.h"
#include "core/aov/conventions.h"
#include "core/aov/exr_header_check.h"
#include "core/aov/file_sets.h"
#include "core/util/error.h"
#include "core/temporal/reprojection.h"
#include "core/util/input_file.h"

namespace residue {
namespace fs = std::filesystem;
namespace {

// What to read for one role.
struct ReadPlan {
  AovRole role = AovRole::Color;
  std::string file;
  std::string layer;
  std::vector<ChannelRef> channels;
  NormalSpace normal_space = NormalSpace::Unknown;
  bool flip_normal_z = false;
  DepthKind depth_kind = DepthKind::Unknown;
  bool depth_from_position = false;
  bool samples_variance = false;  // divide by the header's samplesPerPixel (PassRule)
  bool cycles_vector = false;     // Cycles' Vector pass: turned into Residue's motion convention (PassRule)
  double scale = 1.0;             // the values are read times this
  double depth_background = kDepthBackgroundThreshold;
};

// Whether a file's values are display-encoded sRGB (a PNG or JPEG as most tools write them), which colour AOVs
// must be decoded from: light adds up only in linear values.
bool encoded_srgb(const OIIO::ImageSpec& spec) {
  std::string cs = spec.get_string_attribute("oiio:ColorSpace");
  std::transform(cs.begin(), cs.end(), cs.begin(), [](unsigned char c) { return std::tolower(c); });
  return cs.rfind("srgb", 0) == 0;
}

bool decodes_srgb(const OIIO::ImageSpec& spec, AovRole role) {
  return encoded_srgb(spec) && (role == AovRole::Color || role == AovRole::Albedo || role == AovRole::Reference);
}

float srgb_to_linear(float v) {
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

// An opened input: its channels and per-subimage windows.
struct OpenedFile {
  std::string path;
  std::string format;  // OpenImageIO's name for it: "openexr", "png", ...
  std::vector<ChannelRef> channels;
  std::vector<OIIO::ImageSpec> specs;
};

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

std::string channel_list(const OpenedFile& f, size_t max_names = 40) {
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

// The plan for a whole single-AOV file: its only layer's channels.
ReadPlan plan_from_recognition(const RecognisedAov& r, const std::string& file);

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
  p.normal_space = r.normal_space;
  p.flip_normal_z = r.flip_normal_z;
  p.depth_kind = r.depth_kind;
  p.depth_from_position = r.depth_from_position;
  p.samples_variance = r.samples_variance;
  p.cycles_vector = r.cycles_vector;
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
  if (b.normal_space) p.normal_space = *b.normal_space;
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

// Camera from the header: the OpenEXR worldToCamera attribute, or a JSON Note with "worldToCamera"
// (the Cycles starter set writes one; Blender convention, row-major, p_cam = M p_world).
std::optional<std::array<double, 16>> camera_from_header(const OIIO::ImageSpec& spec, std::vector<std::string>& notes) {
  if (const OIIO::ParamValue* p = spec.find_attribute("worldtocamera", OIIO::TypeMatrix44)) {
    // OpenEXR: row vectors (p' = p M), left-handed camera looking down +z. Ours: column vectors, looking down -z.
    // pbrt-v4 stores its own column-vector matrix there: the translation then sits in the last column, not the
    // last row. (A camera at the world's origin leaves no trace of which; it is read as OpenEXR's.)
    const float* m = static_cast<const float*>(p->data());
    const bool column_vectors = m[12] == 0 && m[13] == 0 && m[14] == 0 && (m[3] != 0 || m[7] != 0 || m[11] != 0);
    if (column_vectors)
      notes.push_back("the worldToCamera attribute is written for column vectors (as pbrt-v4 writes it), not "
                      "OpenEXR's row vectors: read as such");
    std::array<double, 16> out{};
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        out[static_cast<size_t>(r * 4 + c)] = (column_vectors ? m[r * 4 + c] : m[c * 4 + r]) * (r == 2 ? -1.0 : 1.0);
    return out;
  }
  const std::string note = spec.get_string_attribute("Note");
  if (note.empty() || note.front() != '{') return std::nullopt;
  try {
    const auto j = nlohmann::json::parse(note);
    if (j.contains("worldToCamera")) {
      const auto v = j["worldToCamera"].get<std::vector<double>>();
      if (v.size() == 16) {
        std::array<double, 16> out{};
        std::copy(v.begin(), v.end(), out.begin());
        return out;
      }
    }
  } catch (const std::exception&) {
    notes.push_back("the Note attribute looks like JSON but could not be read as a camera");
  }
  return std::nullopt;
}

}  // namespace

FileChannels list_channels(const fs::path& file) {
  OpenedFile f = open_file(file);
  return {f.path, f.channels, f.specs.front().width, f.specs.front().height};
}

struct AovReader::Impl {
  std::map<std::string, OpenedFile> opened;
  std::map<AovRole, ReadPlan> plans;
  AovStack layout;
};

AovReader::~AovReader() = default;

AovReader::AovReader(const std::vector<fs::path>& inputs, const LoadOptions& options) : impl_(std::make_unique<Impl>()) {
  if (inputs.empty()) throw Error(ErrorKind::Usage, "no input file given");
  AovStack& stack = impl_->layout;
  std::map<std::string, OpenedFile>& opened = impl_->opened;
  std::map<AovRole, ReadPlan>& plans = impl_->plans;

  // 1. The primary file and what it holds by its own naming.
  std::vector<fs::path> files = inputs;
  std::error_code ec;
  if (files.size() == 1 && fs::is_directory(files.front(), ec)) files.front() = colour_file_in_folder(files.front());
  std::optional<FileSet> set;
  if (files.size() > 1) {
    set = file_set_from_names(files);
    files = {set->files.at(AovRole::Color)};
  }
  auto open_cached = [&](const fs::path& p) -> const OpenedFile& {
    auto it = opened.find(p.string());
    if (it == opened.end()) it = opened.emplace(p.string(), open_file(p)).first;
    return it->second;
  };
  const OpenedFile& primary = open_cached(files.front());
  Recognition rec = recognise_channels(primary.channels, options.mapping.layer_prefix);
  stack.convention = rec.convention;
  stack.notes = rec.notes;

  for (const RecognisedAov& a : rec.aovs) plans[a.role] = plan_from_recognition(a, primary.path);

  // 2. Single-AOV siblings for what the file itself lacks (Tungsten, OIDN, or files named on the command line).
  const bool single_layer = plans.size() == 1 && plans.count(AovRole::Color);
  if (!set && single_layer && !options.mapping.roles.count(AovRole::Color)) set = sibling_file_set(primary.path);
  if (set) {
    bool used = false;
    for (const auto& [role, path] : set->files) {
      if (role == AovRole::Color || plans.count(role)) continue;
      if (role == AovRole::Reference && (!options.load_reference || options.reference)) continue;
      plans[role] = whole_file_plan(role, open_cached(path));
      used = true;
    }
    if (used || files.size() != inputs.size()) stack.convention = set->convention;
    // What the convention's files hold (a file-set AOV has no layer name to tell by).
    for (auto& [role, plan] : plans) {
      if (!set->files.count(role) || plan.file != set->files.at(role).string()) continue;
      if (role == AovRole::Normal) plan.normal_space = set->normal_space;
      if (role == AovRole::Depth) plan.depth_kind = set->depth_kind;
    }
  }
  // A layered render's reference beside it under the data sets' name, when it has the render's size.
  if (!set && !plans.count(AovRole::Reference) && options.load_reference && !options.reference) {
    if (const auto ref = reference_beside(primary.path)) {
      const OpenedFile& r = open_cached(*ref);
      const OIIO::ImageSpec& rs = r.specs.front();
      const OIIO::ImageSpec& ps = primary.specs.front();
      if (rs.full_width == ps.full_width && rs.full_height == ps.full_height) {
        plans[AovRole::Reference] = whole_file_plan(AovRole::Reference, r);
        stack.notes.push_back("reference: '" + ref->filename().string() + "' beside the render (-r names another)");
      } else {
        stack.notes.push_back("'" + ref->string() + "' beside the render has another size: not used as its reference");
      }
    }
  }
  if (plans.count(AovRole::Reference) && !options.load_reference) plans.erase(AovRole::Reference);

  // 3. Explicit mappings and a reference file override everything above.
  for (const auto& [role, binding] : options.mapping.roles) {
    const OpenedFile& f = open_cached(binding.file.empty() ? fs::path(primary.path) : fs::path(binding.file));
    plans[role] = plan_from_binding(role, binding, f);
    stack.convention = rec.convention.empty() ? "explicit mapping" : rec.convention + " + explicit mapping";
  }
  if (options.reference) plans[AovRole::Reference] = whole_file_plan(AovRole::Reference, open_cached(*options.reference));

  // A variance of the samples becomes the estimate's: the samples' variance over their count.
  if (auto it = plans.find(AovRole::Variance); it != plans.end() && it->second.samples_variance) {
    const ReadPlan& v = it->second;
    const OIIO::ImageSpec& spec = open_cached(v.file).specs.at(static_cast<size_t>(v.channels.front().subimage));
    const int spp = spec.get_int_attribute("samplesPerPixel", 0);
    if (spp > 0) {
      it->second.scale = 1.0 / spp;
      stack.notes.push_back("variance: the samples' variance in '" + v.layer + "' divided by the samplesPerPixel "
                            "header (" + std::to_string(spp) + ") to give the pixel estimate's");
    } else {
      stack.notes.push_back("no variance: '" + v.layer + "' is the samples' variance and the header has no "
                            "samplesPerPixel to turn it into the pixel estimate's");
      plans.erase(it);
    }
  }

  if (!plans.count(AovRole::Color) && !options.mapping.layer_prefix.empty()) {
    const std::vector<std::string> layers = layer_names(primary.channels);
    const auto same = [&](const std::string& l) { return OIIO::Strutil::iequals(l, options.mapping.layer_prefix); };
    if (std::none_of(layers.begin(), layers.end(), same)) {
      std::string list;
      for (const auto& l : layers) list += (list.empty() ? "" : ", ") + l;
      throw Error(ErrorKind::Input, "--layer '" + options.mapping.layer_prefix + "': '" + primary.path +
                                        "' has no such layer; its layers: " + (list.empty() ? "(none: every channel is at the root)" : list));
    }
  }
  if (!plans.count(AovRole::Color))
    throw Error(ErrorKind::Input, "'" + primary.path + "': no colour (beauty) channels recognised; expected " +
                                      expected_text(AovRole::Color) + "; found channels " + channel_list(primary));
  // Integer channels (object or material IDs) hold no light: read as float they would be scaled by 1/(2^32-1).
  for (const auto& [role, plan] : plans)
    for (const ChannelRef& c : plan.channels)
      if (c.pixel_type == "uint" || c.pixel_type == "uint32")
        throw Error(ErrorKind::Input, "'" + plan.file + "': the " + to_string(role) + " channel '" + c.name +
                                          "' is an integer (uint) channel, such as an ID pass; AOVs are read from "
                                          "half or float channels (map another with --map " + to_string(role) + "=...)");
  if (options.normal_space && plans.count(AovRole::Normal)) {
    plans[AovRole::Normal].normal_space = *options.normal_space;
    plans[AovRole::Normal].flip_normal_z = false;
    // The position pass a depth was read from is in the normals' space: in world space its z is not a depth.
    if (*options.normal_space == NormalSpace::World && plans.count(AovRole::Depth) &&
        plans[AovRole::Depth].depth_from_position) {
      stack.notes.push_back("no depth: it would be the z of the position pass '" + plans[AovRole::Depth].layer +
                            "', which is in world space like the normals");
      plans.erase(AovRole::Depth);
    }
  }

  // 4. The grid: the colour source's data window. Other AOVs must share its display window.
  const ReadPlan& colour = plans.at(AovRole::Color);
  const OIIO::ImageSpec& cspec = open_cached(colour.file).specs.at(static_cast<size_t>(colour.channels.front().subimage));
  stack.data_window = {cspec.x, cspec.y, cspec.width, cspec.height};
  stack.display_width = cspec.full_width;
  stack.display_height = cspec.full_height;
  for (const auto& [role, plan] : plans) {
    const OIIO::ImageSpec& s = open_cached(plan.file).specs.at(static_cast<size_t>(plan.channels.front().subimage));
    if (s.full_width != cspec.full_width || s.full_height != cspec.full_height)
      throw Error(ErrorKind::Input, std::string("size mismatch: the ") + to_string(role) + " AOV in '" + plan.file +
                                        "' is " + std::to_string(s.full_width) + "x" + std::to_string(s.full_height) +
                                        " but the colour in '" + colour.file + "' is " +
                                        std::to_string(cspec.full_width) + "x" + std::to_string(cspec.full_height));
  }

  std::set<std::string> non_exr;
  for (const auto& [role, plan] : plans) {
    const OpenedFile& f = open_cached(plan.file);
    if (f.format == "openexr" || !non_exr.insert(f.path).second) continue;
    const auto& spec = f.specs.at(static_cast<size_t>(plan.channels.front().subimage));
    stack.notes.push_back(encoded_srgb(spec)
                              ? "'" + f.path + "' is an sRGB-encoded " + f.format + " file: its colour is decoded to "
                                "linear light (8 bits: expect banding in dark regions)"
                              : "'" + f.path + "' is a " + f.format + " file that says it is linear: its values are "
                                "used as stored");
  }
  for (const auto& [role, plan] : plans) {
    if (role == AovRole::Normal) stack.normal_space = plan.normal_space;
    if (role == AovRole::Depth) stack.depth_kind = plan.depth_kind;
  }
  // The layout: every AOV present, described, without pixels.
  for (const auto& [role, plan] : plans) stack.emplace(role).source = describe(plan);
  if (stack.normal_space == NormalSpace::Unknown && plans.count(AovRole::Normal))
    stack.notes.push_back("normal space unknown: give --normal-space camera|world if the network should know");
  stack.metadata = cspec.extra_attribs;
  stack.world_to_camera = camera_from_header(cspec, stack.notes);
  if (stack.normal_space == NormalSpace::World && !stack.world_to_camera)
    stack.notes.push_back("normals are in world space and no camera is known: they cannot be made view-space");
}

const AovStack& AovReader::layout() const { return impl_->layout; }

AovStack AovReader::read(const Rect& rect, const std::vector<AovRole>& roles) const {
  const AovStack& layout = impl_->layout;
  if (rect.empty() || !Rect{0, 0, layout.data_window.width, layout.data_window.height}.contains(rect))
    throw Error(ErrorKind::Usage, "region " + rect.to_string() + " is not inside the " +
                                      std::to_string(layout.data_window.width) + "x" +
                                      std::to_string(layout.data_window.height) + " image");
  AovStack stack = layout;  // everything but the pixels, which are read below
  const Rect grid{layout.data_window.x + rect.x, layout.data_window.y + rect.y, rect.width, rect.height};
  const std::map<AovRole, ReadPlan>& plans = impl_->plans;
  // 5. Read, one pass per file.
  std::map<std::string, std::vector<const ReadPlan*>> by_file;
  for (const auto& [role, plan] : plans)
    if (roles.empty() || std::find(roles.begin(), roles.end(), role) != roles.end()) by_file[plan.file].push_back(&plan);
  std::map<AovRole, Aov> loaded;
  for (const auto& [file, file_plans] : by_file) read_plans(impl_->opened.at(file), file_plans, grid, loaded);

  // 6. Normalise conventions and count what is unusual.
  for (auto& [role, aov] : loaded) {
    const ReadPlan& plan = plans.at(role);
    if (plan.scale != 1.0)
      for (int64_t y = 0; y < aov.image.height(); ++y)
        for (float& v : aov.image.row(y)) v = static_cast<float>(v * plan.scale);
    stack.depth_background_pixels += normalise_aov(role, plan.flip_normal_z, plan.depth_background, aov);
    if (role == AovRole::Motion && plan.cycles_vector) aov.image = motion_from_cycles_vector(aov.image);
    if (aov.uncovered_pixels > 0)
      stack.notes.push_back(std::string("the ") + to_string(role) + " AOV does not cover " +
                            std::to_string(aov.uncovered_pixels) + " pixels of the colour's data window (" +
                            (role == AovRole::Reference ? "not scored: metrics exclude them" : "set to 0") + ")");
  }

  for (auto& [role, aov] : loaded) {
    // A guide with no finite value is read as 0 everywhere (features sanitise it): say so, as the model then
    // has no guide at all.
    if ((role == AovRole::Albedo || role == AovRole::Normal) && aov.image.size() > 0 &&
        aov.non_finite.total() == static_cast<int64_t>(aov.image.size()))
      stack.notes.push_back(std::string("the ") + to_string(role) + " AOV has no finite value (" +
                            std::to_string(aov.non_finite.nan) + " NaN, " + std::to_string(aov.non_finite.inf) +
                            " Inf): it is read as 0, so the model has no " + to_string(role) + " to go by; re-render the pass");
    stack.emplace(role) = std::move(aov);
  }

  return stack;
}

int64_t normalise_aov(AovRole role, bool flip_normal_z, double depth_background, Aov& aov) {
  int64_t background = 0;
  if (role == AovRole::Normal && flip_normal_z)
    for (int64_t y = 0; y < aov.image.height(); ++y)
      for (int64_t x = 0; x < aov.image.width(); ++x) aov.image.at(x, y, 2) = -aov.image.at(x, y, 2);
  if (role == AovRole::Depth) {
    for (int64_t y = 0; y < aov.image.height(); ++y)
      for (float& v : aov.image.row(y))
        if (v >= depth_background) {  // +Inf too
          v = 0.0f;
          ++background;
        }
  }
  aov.non_finite = count_non_finite(aov.image);
  return background;
}

AovStack load_aov_stack(const std::vector<fs::path>& inputs, const LoadOptions& options) {
  const AovReader reader(inputs, options);
  const Rect& dw = reader.layout().data_window;
  return reader.read({0, 0, dw.width, dw.height});
}

}  // namespace residue
