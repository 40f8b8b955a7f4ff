// `import residue`: core's loading, denoising, metrics and EXR writing for Python, NumPy in and out.
// Images are float32 arrays of height x width x channels (C order), copied in and out: core owns its images.
// Long calls (denoise, FLIP) release the GIL; a progress callback takes it again for each call. Core's errors
// arrive as residue.Error with core's message; a cancelled denoise as residue.Cancelled.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <map>
#include <memory>
#include <string>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/method_registry.h"
#include "core/denoise/provenance_of.h"
#include "core/features/features.h"
#include "core/io/exr_writer.h"
#include "core/metrics/flip.h"
#include "core/metrics/metrics.h"
#include "core/nn/model_card.h"
#include "core/temporal/frame_window.h"
#include "core/temporal/temporal_blend.h"
#include "core/nn/model_registry.h"
#include "core/io/frame_sequence.h"
#include "core/io/provenance.h"
#include "core/util/cancel.h"
#include "core/util/error.h"

namespace py = pybind11;
using namespace residue;

namespace {

using Array = py::array_t<float, py::array::c_style | py::array::forcecast>;

Array to_array(const Image& image) {
  Array a({image.height(), image.width(), static_cast<int64_t>(image.channels())});
  std::copy(image.data(), image.data() + image.size(), a.mutable_data());
  return a;
}

Image to_image(const Array& a, const char* what) {
  if (a.ndim() != 3 && a.ndim() != 2)
    throw Error(ErrorKind::Usage, std::string(what) + ": expected an array of height x width x channels, not " +
                                      std::to_string(a.ndim()) + " dimensions");
  const int channels = a.ndim() == 3 ? static_cast<int>(a.shape(2)) : 1;
  Image image(a.shape(1), a.shape(0), channels);
  std::copy(a.data(), a.data() + image.size(), image.data());
  return image;
}

// The process's models, each file read once (as the CLI keeps them for the frames of a sequence).
nn::ModelRegistry& models() {
  static nn::ModelRegistry registry;
  return registry;
}

py::dict scores_dict(const metrics::Scores& s) {
  py::dict d;
  d["relmse"] = s.relmse;
  d["mse"] = s.mse;
  d["psnr"] = s.psnr;
  d["ssim"] = s.ssim;
  d["pixels"] = s.pixels;
  d["excluded_test"] = s.excluded_test;
  d["excluded_reference"] = s.excluded_reference;
  return d;
}

std::optional<Array> aov_array(const std::optional<Aov>& aov) {
  return aov ? std::optional<Array>(to_array(aov->image)) : std::nullopt;
}

using Roi = std::optional<std::tuple<int64_t, int64_t, int64_t, int64_t>>;  // x, y, width, height

std::optional<Rect> to_rect(const Roi& roi) {
  if (!roi) return std::nullopt;
  const auto [x, y, w, h] = *roi;
  return Rect{x, y, w, h};
}

// What every denoise call takes, as DenoiseOptions.
DenoiseOptions denoise_options(const std::string& precision, float strength, int ensemble, int64_t tile,
                               bool energy_correction, const Roi& roi, const CancelToken* cancel) {
  DenoiseOptions o;
  o.precision = nn::parse_precision(precision);
  o.strength = strength;
  o.ensemble = ensemble;
  o.tile = tile;
  o.energy_correction = energy_correction;
  o.roi = to_rect(roi);
  o.cancel = cancel;
  return o;
}

// Runs `method` on `stack` with the GIL released; progress(done, total) and on_tile((x, y, w, h), pixels) take it
// again for each tile (on_tile for the result's tiles only, not a prefilter's); either returning False stops.
Image run_denoise(const AovStack& stack, const Method& method, const DenoiseOptions& o,
                  const std::function<bool(int64_t, int64_t)>& progress, const py::object& on_tile_fn,
                  DenoiseStats& stats) {
  TileCallback on_tile;
  if (progress || !on_tile_fn.is_none())
    on_tile = [&progress, &on_tile_fn](const TileEvent& e, const Image& pixels) {
      py::gil_scoped_acquire gil;
      if (!on_tile_fn.is_none() && e.result) {
        const py::object go = on_tile_fn(py::make_tuple(e.rect.x, e.rect.y, e.rect.width, e.rect.height), to_array(pixels));
        if (go.is(py::bool_(false))) return false;  // None (a function that returns nothing) goes on
      }
      return progress ? progress(e.work_done, e.work_total) : true;
    };
  py::gil_scoped_release released;
  return denoise(stack, method, o, on_tile, &stats);
}

py::dict card_dict(const nn::ModelCard& c) {
  py::dict d;
  d["family"] = c.family;
  d["alias_of"] = c.alias_of;
  d["method"] = nn::to_string(c.method);
  d["architecture"] = c.architecture;
  d["ensemble"] = c.ensemble;
  d["gflop_per_mp"] = c.gflop_per_mp;
  d["variants"] = c.variants;
  d["description"] = c.description;
  d["file"] = c.file.string();
  if (c.validation) d["validation"] = py::dict(py::arg("relmse") = c.validation->relmse, py::arg("ssim") = c.validation->ssim,
                                               py::arg("scenes") = c.validation->scenes);
  else d["validation"] = py::none();
  d["fp32_s_per_mp"] = c.seconds_per_mp(nn::Precision::FP32);
  d["bf16_s_per_mp"] = c.seconds_per_mp(nn::Precision::BF16);
  return d;
}

}  // namespace

PYBIND11_MODULE(residue, m) {
  m.doc() = "Residue: denoise Monte Carlo renders with a direct residual network, and score the result.";
  static py::exception<Error> error(m, "Error");
  static py::exception<Cancelled> cancelled(m, "Cancelled");
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Cancelled& e) {
      cancelled(e.what());
    } catch (const Error& e) {
      error(e.what());
    }
  });

  py::class_<CancelToken, std::shared_ptr<CancelToken>>(m, "CancelToken",
                                                        "Stops a denoise from any thread: pass it as cancel=.")
      .def(py::init<>())
      .def("cancel", &CancelToken::request, "Asks the denoise to stop (within one network layer).")
      .def_property_readonly("cancelled", &CancelToken::requested);

  py::class_<AovStack, std::shared_ptr<AovStack>>(m, "AovStack", "A render's AOVs as loaded and recognised.")
      .def_property_readonly("color", [](const AovStack& s) { return to_array(s.color.image); })
      .def_property_readonly("albedo", [](const AovStack& s) { return aov_array(s.albedo); })
      .def_property_readonly("normal", [](const AovStack& s) { return aov_array(s.normal); })
      .def_property_readonly("depth", [](const AovStack& s) { return aov_array(s.depth); })
      .def_property_readonly("variance", [](const AovStack& s) { return aov_array(s.variance); })
      .def_property_readonly("reference", [](const AovStack& s) { return aov_array(s.reference); })
      .def_property_readonly("motion", [](const AovStack& s) { return aov_array(s.motion); })
      .def_property_readonly("convention", [](const AovStack& s) { return s.convention; },
                             "The renderer's naming that was recognised")
      .def_property_readonly("notes", [](const AovStack& s) { return s.notes; },
                             "What the loader assumed or left out")
      .def_property_readonly("width", &AovStack::width)
      .def_property_readonly("height", &AovStack::height);

  m.def(
      "load",
      [](const std::string& path, std::optional<std::string> reference) {
        LoadOptions o;
        if (reference) o.reference = *reference;
        return std::make_shared<AovStack>(load_aov_stack({path}, o));
      },
      py::arg("path"), py::arg("reference") = std::nullopt,
      "Loads a render: one multilayer EXR, or a folder of single-AOV files. A reference.exr beside it is taken as "
      "its reference unless `reference` names another.");

  m.def(
      "load_frames",
      [](const std::string& pattern, std::optional<std::string> frames, std::optional<std::string> reference) {
        const auto p = io::FramePattern::parse(pattern);
        if (!p) throw Error(ErrorKind::Usage, "'" + pattern + "' names no frame number (shot.####.exr or shot.%04d.exr)");
        std::optional<io::FramePattern> ref;
        if (reference) {
          ref = io::FramePattern::parse(*reference);
          if (!ref) throw Error(ErrorKind::Usage, "reference '" + *reference + "' names no frame number");
        }
        const std::vector<int64_t> numbers = frames ? io::parse_frame_spec(*frames) : io::find_frames(*p);
        if (numbers.empty()) throw Error(ErrorKind::Input, "no frame of '" + pattern + "' exists");
        std::vector<std::shared_ptr<AovStack>> out;
        py::gil_scoped_release released;
        for (const int64_t f : numbers) {
          LoadOptions o;
          if (ref) o.reference = ref->path(f);
          out.push_back(std::make_shared<AovStack>(load_aov_stack({p->path(f)}, o)));
        }
        return out;
      },
      py::arg("pattern"), py::arg("frames") = std::nullopt, py::arg("reference") = std::nullopt,
      "Loads frames of a shot by pattern (shot.####.exr or shot.%04d.exr): those of `frames` (a spec as "
      "residue-cli's --frames takes it: 1001-1100, 1,5,7-20:2) in its order, else every frame that exists, "
      "ascending; `reference` a pattern of their references. A frame that is missing is an error naming its file. "
      "denoise_frame and temporal_blend take consecutive frames.");

  m.def(
      "stack",
      [](const Array& color, std::optional<Array> albedo, std::optional<Array> normal, std::optional<Array> depth,
         std::optional<Array> reference, const std::string& normal_space) {
        auto stack = std::make_shared<AovStack>();
        stack->convention = "arrays";
        stack->color.image = to_image(color, "color");
        stack->color.source.file = "(array color)";
        const auto put = [&](AovRole role, const std::optional<Array>& a, const char* what) {
          if (!a) return;
          Aov& aov = stack->emplace(role);
          aov.image = to_image(*a, what);
          if (aov.image.width() != stack->width() || aov.image.height() != stack->height())
            throw Error(ErrorKind::Input, std::string(what) + " is " + std::to_string(aov.image.width()) + "x" +
                                              std::to_string(aov.image.height()) + " but the colour is " +
                                              std::to_string(stack->width()) + "x" + std::to_string(stack->height()));
          aov.source.file = std::string("(array ") + what + ")";
        };
        put(AovRole::Albedo, albedo, "albedo");
        put(AovRole::Normal, normal, "normal");
        put(AovRole::Depth, depth, "depth");
        put(AovRole::Reference, reference, "reference");
        const auto space = normal_space_from_string(normal_space);
        if (!space)
          throw Error(ErrorKind::Usage, "normal_space: expected camera, world or unknown, not '" + normal_space + "'");
        stack->normal_space = *space;
        stack->data_window = {0, 0, stack->width(), stack->height()};
        stack->display_width = stack->width();
        stack->display_height = stack->height();
        return stack;
      },
      py::arg("color"), py::arg("albedo") = std::nullopt, py::arg("normal") = std::nullopt,
      py::arg("depth") = std::nullopt, py::arg("reference") = std::nullopt, py::arg("normal_space") = "camera",
      "A render from arrays by role (colour H x W x 3; albedo and normal H x W x 3, depth H x W x 1), for images "
      "that are not in files. Normals in camera space have +z towards the viewer.");

  m.def(
      "denoise",
      [](const AovStack& stack, const std::string& model, const std::string& precision, float strength, int ensemble,
         int64_t tile, bool energy_correction, const Roi& roi, std::function<bool(int64_t, int64_t)> progress,
         std::shared_ptr<CancelToken> cancel, py::object on_tile) {
        const DenoiseOptions o = denoise_options(precision, strength, ensemble, tile, energy_correction, roi, cancel.get());
        const std::unique_ptr<Method> method = resolve_method(model, feature_set_for(stack), models());
        DenoiseStats stats;
        return to_array(run_denoise(stack, *method, o, progress, on_tile, stats));
      },
      py::arg("stack"), py::arg("model") = nn::kDefaultModel, py::arg("precision") = "fp32", py::arg("strength") = 1.0f,
      py::arg("ensemble") = 0, py::arg("tile") = 0, py::arg("energy_correction") = true, py::arg("roi") = std::nullopt,
      py::arg("progress") = nullptr, py::arg("cancel") = nullptr, py::arg("on_tile") = py::none(),
      "Denoises a loaded render with a model (a name as residue-cli's -m takes it: multiscale, best, oidn, "
      "bilateral, or a file) and returns its colour, height x width x 3. roi=(x, y, w, h) denoises that rectangle "
      "only (the noisy colour elsewhere). progress(done, total) is called with the work done after every tile; "
      "returning False stops the run (residue.Cancelled). on_tile((x, y, w, h), pixels) is called with each tile of "
      "the result as the network left it (h x w x 3, for a preview: the energy correction and the strength, which "
      "need whole bands, come later); returning False stops the run too.");

  m.def(
      "denoise_to_exr",
      [](const AovStack& stack, const std::string& path, const std::string& model, const std::string& precision,
         float strength, int ensemble, int64_t tile, bool energy_correction, const Roi& roi, bool half, bool overwrite,
         std::function<bool(int64_t, int64_t)> progress, std::shared_ptr<CancelToken> cancel, py::object on_tile) {
        const DenoiseOptions o = denoise_options(precision, strength, ensemble, tile, energy_correction, roi, cancel.get());
        const std::unique_ptr<Method> method = resolve_method(model, feature_set_for(stack), models());
        io::ExrWriteOptions exr;
        exr.pixel_type = half ? io::PixelType::Half : io::PixelType::Float;
        exr.overwrite = overwrite;
        keep_render_header(exr, stack);
        io::prepare_exr_output(path, exr);  // before the work: a file that may not be replaced stops it here
        DenoiseStats stats;
        const Image out = run_denoise(stack, *method, o, progress, on_tile, stats);
        io::record(exr.residue_attributes, {.source = stack.color.source.file, .written_by = "residue (Python)"});
        io::record(exr.residue_attributes, provenance_of(*method, stats));
        io::write_exr(path, out, exr);
        return py::dict(py::arg("model") = method->name(), py::arg("architecture") = method->architecture(),
                        py::arg("backend") = stats.backend, py::arg("seconds") = stats.seconds,
                        py::arg("tiles") = stats.tiles);
      },
      py::arg("stack"), py::arg("path"), py::arg("model") = nn::kDefaultModel, py::arg("precision") = "fp32",
      py::arg("strength") = 1.0f, py::arg("ensemble") = 0, py::arg("tile") = 0, py::arg("energy_correction") = true,
      py::arg("roi") = std::nullopt, py::arg("half") = true, py::arg("overwrite") = false, py::arg("progress") = nullptr,
      py::arg("cancel") = nullptr, py::arg("on_tile") = py::none(),
      "denoise() written as residue-cli denoise writes it: the render's header and windows, and residue:* "
      "provenance (model, architecture, backend, post-steps, time). Returns what ran.");

  m.def(
      "models",
      [] {
        py::list out;
        for (const nn::ModelCard& c : nn::list_model_cards()) out.append(card_dict(c));
        return out;
      },
      "The model cards: every name denoise() takes, with its method, architecture, cost, variants and the "
      "validation and benchmark numbers measured for it (as residue-cli models lists them).");

  m.def(
      "error_map",
      [](const Array& test, const Array& reference, const std::string& kind, double eps) {
        const auto k = metrics::map_kind_from_string(kind);
        if (!k) throw Error(ErrorKind::Usage, "kind: expected abs, se, rse or ssim, not '" + kind + "'");
        metrics::Options o;
        o.eps = eps;
        return to_array(metrics::error_map(to_image(test, "test"), to_image(reference, "reference"), *k, o));
      },
      py::arg("test"), py::arg("reference"), py::arg("kind") = "rse", py::arg("eps") = 0.01,
      "A per-pixel map, H x W x 1: abs, se, rse (its mean is relMSE) or ssim; NaN where a pixel is excluded.");

  m.def(
      "metrics",
      [](const Array& test, const Array& reference, double eps) {
        metrics::Options o;
        o.eps = eps;
        return scores_dict(metrics::compare(to_image(test, "test"), to_image(reference, "reference"), o));
      },
      py::arg("test"), py::arg("reference"), py::arg("eps") = 0.01,
      "relMSE, MSE, PSNR and SSIM of `test` against `reference`, as residue-cli eval computes them.");

  m.def(
      "flip",
      [](const Array& test, const Array& reference) {
        const Image t = to_image(test, "test"), r = to_image(reference, "reference");
        metrics::FlipResult f;
        {
          py::gil_scoped_release released;
          f = metrics::hdr_flip(t, r);
        }
        py::dict d;
        d["mean"] = f.mean;
        d["map"] = to_array(f.map);
        d["exposures"] = py::make_tuple(f.exposures.start, f.exposures.stop, f.exposures.count);
        return d;
      },
      py::arg("test"), py::arg("reference"),
      "HDR-FLIP of linear `test` against `reference`: its mean, its per-pixel map and the exposures (start, stop, "
      "count) it used, as NVIDIA's reference code computes them.");

  m.def(
      "denoise_frame",
      [](const std::vector<std::shared_ptr<AovStack>>& frames, int t, const std::string& model,
         const std::string& precision, float strength, int ensemble, int64_t tile, bool energy_correction,
         const Roi& roi, std::function<bool(int64_t, int64_t)> progress, std::shared_ptr<CancelToken> cancel,
         py::object on_tile) {
        const int n = static_cast<int>(frames.size());
        if (t < 0 || t >= n)
          throw Error(ErrorKind::Usage, "denoise_frame: t = " + std::to_string(t) + " is not a frame of the " +
                                            std::to_string(n) + " given");
        const DenoiseOptions o = denoise_options(precision, strength, ensemble, tile, energy_correction, roi, cancel.get());
        AovStack frame = *frames[static_cast<size_t>(t)];
        const std::unique_ptr<Method> method = resolve_method(model, feature_set_for(frame), models());
        std::vector<int> missing;
        if (method->frame_radius() > 0) {
          py::gil_scoped_release released;
          missing = attach_neighbours(frame, method->frame_radius(), [&](int d) -> const AovStack* {
            return t + d >= 0 && t + d < n ? frames[static_cast<size_t>(t + d)].get() : nullptr;
          });
        }
        DenoiseStats stats;
        const Image out = run_denoise(frame, *method, o, progress, on_tile, stats);
        return py::make_tuple(to_array(out), missing);
      },
      py::arg("frames"), py::arg("t"), py::arg("model") = nn::kDefaultTemporalModel, py::arg("precision") = "fp32",
      py::arg("strength") = 1.0f, py::arg("ensemble") = 0, py::arg("tile") = 0, py::arg("energy_correction") = true,
      py::arg("roi") = std::nullopt, py::arg("progress") = nullptr, py::arg("cancel") = nullptr,
      py::arg("on_tile") = py::none(),
      "Frame t of a shot (frames: consecutive frames as loaded, each with its motion AOV) denoised as residue-cli "
      "denoise --temporal denoises it: a temporal model (multiscale-temporal unless model names another) reads the "
      "neighbours it needs warped to frame t; frames beyond the list's ends are missing and read as not valid. "
      "Another model denoises frame t alone. Returns (colour, the neighbour offsets that were missing).");

  m.def(
      "temporal_blend",
      [](const std::vector<std::shared_ptr<AovStack>>& frames, const std::vector<Array>& denoised, int t,
         double tolerance) {
        const int n = static_cast<int>(frames.size());
        if (static_cast<int>(denoised.size()) != n)
          throw Error(ErrorKind::Usage, "temporal_blend: " + std::to_string(n) + " frames but " +
                                            std::to_string(denoised.size()) + " denoised images");
        if (t < 0 || t >= n)
          throw Error(ErrorKind::Usage, "temporal_blend: t = " + std::to_string(t) + " is not a frame of the " +
                                            std::to_string(n) + " given");
        std::map<int, Image> images;  // frames t-1..t+1 of those given, by offset
        for (int offset = -1; offset <= 1; ++offset)
          if (t + offset >= 0 && t + offset < n)
            images[offset] = to_image(denoised[static_cast<size_t>(t + offset)], "denoised");
        Image out;
        {
          py::gil_scoped_release released;
          out = temporal_blend_frames(*frames[static_cast<size_t>(t)], images.at(0), [&](int offset) -> DenoisedFrame {
            const auto it = images.find(offset);
            if (it == images.end()) return {};
            return {frames[static_cast<size_t>(t + offset)].get(), &it->second};
          }, {.tolerance = tolerance});
        }
        return to_array(out);
      },
      py::arg("frames"), py::arg("denoised"), py::arg("t"), py::arg("tolerance") = 0.5,
      "Frame t's denoised colour averaged with frames t-1 and t+1's, brought to it along the motion vectors and "
      "weighted down by their colour difference (0 beyond `tolerance`), as residue-cli denoise --temporal-blend does. "
      "`frames`: consecutive frames of a shot (each with its motion AOV), `denoised`: each one's denoised colour.");

  m.def(
      "write_exr",
      [](const std::string& path, const Array& image, bool half, bool overwrite) {
        io::ExrWriteOptions o;
        o.pixel_type = half ? io::PixelType::Half : io::PixelType::Float;
        o.overwrite = overwrite;
        io::write_exr(path, to_image(image, "image"), o);
      },
      py::arg("path"), py::arg("image"), py::arg("half") = true, py::arg("overwrite") = false,
      "Writes an image as an EXR, atomically; an existing file is replaced only with overwrite=True.");
}
