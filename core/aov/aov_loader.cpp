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
#include "core/aov/file_sets.h"
#include "core/aov/read_plan.h"
#include "core/temporal/reprojection.h"
#include "core/util/error.h"

namespace residue {
namespace fs = std::filesystem;
namespace {

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
      if (role == AovRole::Normal) plan.meaning.normal_space = set->normal_space;
      if (role == AovRole::Depth) plan.meaning.depth_kind = set->depth_kind;
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
  if (auto it = plans.find(AovRole::Variance); it != plans.end() && it->second.meaning.samples_variance) {
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
    plans[AovRole::Normal].meaning.normal_space = *options.normal_space;
    plans[AovRole::Normal].meaning.flip_normal_z = false;
    // The position pass a depth was read from is in the normals' space: in world space its z is not a depth.
    if (*options.normal_space == NormalSpace::World && plans.count(AovRole::Depth) &&
        plans[AovRole::Depth].meaning.depth_from_position) {
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
    if (role == AovRole::Normal) stack.normal_space = plan.meaning.normal_space;
    if (role == AovRole::Depth) stack.depth_kind = plan.meaning.depth_kind;
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
    stack.depth_background_pixels += normalise_aov(role, plan.meaning.flip_normal_z, plan.depth_background, aov);
    if (role == AovRole::Motion && plan.meaning.cycles_vector) aov.image = motion_from_cycles_vector(aov.image);
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
