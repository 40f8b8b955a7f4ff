// `import residue`: core's loading, denoising, metrics and EXR writing for Python, NumPy in and out.
// Images are float32 arrays of height x width x channels (C order), copied in and out: core owns its images.
// Long calls (denoise, FLIP) release the GIL; a progress callback takes it again for each call. Core's errors
// arrive as residue.Error with core's message; a cancelled denoise as residue.Cancelled.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <string>

#include "core/aov/aov_loader.h"
#include "core/denoise/denoiser.h"
#include "core/denoise/method_registry.h"
#include "core/features/features.h"
#include "core/io/exr_writer.h"
#include "core/metrics/flip.h"
#include "core/metrics/metrics.h"
#include "core/nn/model_registry.h"
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
      "denoise",
      [](const AovStack& stack, const std::string& model, const std::string& precision, float strength, int ensemble,
         int64_t tile, bool energy_correction, std::function<bool(int64_t, int64_t)> progress,
         std::shared_ptr<CancelToken> cancel) {
        DenoiseOptions o;
        o.precision = nn::parse_precision(precision);
        o.strength = strength;
        o.ensemble = ensemble;
        o.tile = tile;
        o.energy_correction = energy_correction;
        o.cancel = cancel.get();
        const std::unique_ptr<Method> method = resolve_method(model, feature_set_for(stack), models());
        TileCallback on_tile;
        if (progress)
          on_tile = [&progress](const TileEvent& e, const Image&) {
            py::gil_scoped_acquire gil;
            return progress(e.work_done, e.work_total);
          };
        Image out;
        {
          py::gil_scoped_release released;
          out = denoise(stack, *method, o, on_tile);
        }
        return to_array(out);
      },
      py::arg("stack"), py::arg("model") = nn::kDefaultModel, py::arg("precision") = "fp32", py::arg("strength") = 1.0f,
      py::arg("ensemble") = 0, py::arg("tile") = 0, py::arg("energy_correction") = true,
      py::arg("progress") = nullptr, py::arg("cancel") = nullptr,
      "Denoises a loaded render with a model (a name as residue-cli's -m takes it: multiscale, best, oidn, "
      "bilateral, or a file) and returns its colour, height x width x 3. progress(done, total) is called with the "
      "work done after every tile; returning False stops the run (residue.Cancelled).");

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
