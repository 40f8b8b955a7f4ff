#include "denoise_frame.h"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <set>

#include "core/denoise/method_registry.h"
#include "core/denoise/provenance_of.h"
#include "core/features/features.h"
#include "core/io/atomic_file.h"
#include "core/io/provenance.h"
#include "core/nn/model_alias.h"
#include "core/nn/model_card.h"
#include "core/metrics/metrics.h"
#include "core/temporal/frame_window.h"
#include "core/temporal/temporal_blend.h"
#include "core/util/error.h"

namespace residue::cli {
namespace {

// Draws "[#####.....] 12/40 tiles" on a terminal, or one line per ~10% otherwise.
class ProgressReporter {
 public:
  ProgressReporter() : tty_(isatty(STDERR_FILENO) != 0) {}
  void tile(const TileEvent& e) {
    if (tty_) {
      const int width = 30;
      const int filled = static_cast<int>(width * e.done / std::max<int64_t>(1, e.total));
      std::fprintf(stderr, "\r[%s%s] %lld/%lld tiles", std::string(static_cast<size_t>(filled), '#').c_str(),
                   std::string(static_cast<size_t>(width - filled), '.').c_str(), static_cast<long long>(e.done),
                   static_cast<long long>(e.total));
      if (e.done == e.total) std::fprintf(stderr, "\n");
    } else if (e.done == e.total || e.done * 10 / e.total != (e.done - 1) * 10 / e.total) {
      std::fprintf(stderr, "denoise: %lld/%lld tiles\n", static_cast<long long>(e.done), static_cast<long long>(e.total));
    }
  }

 private:
  bool tty_;
};

// Bytes an in-memory denoise holds for the whole image: every AOV as float, plus the output.
size_t whole_image_bytes(const AovStack& layout) {
  return static_cast<size_t>((layout.channel_count() + 3) * layout.data_window.area()) * sizeof(float);
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The files a render is read from (every AOV's, the reference's).
std::vector<std::string> input_files(const AovStack& layout) {
  std::vector<std::string> files = {layout.color.source.file};
  for (const std::optional<Aov>* a : {&layout.albedo, &layout.normal, &layout.depth, &layout.variance, &layout.reference})
    if (a->has_value()) files.push_back((*a)->source.file);
  return files;
}

// Every check on the output, before any work: the output may not be one of the files read (even with --force:
// the render's AOVs would be lost), then prepare_exr_output()'s (name, compression, folder, overwrite).
void check_output(const std::string& output, const AovStack& layout, const io::ExrWriteOptions& w) {
  const std::vector<std::string> read = input_files(layout);
  io::refuse_input_as_output(output, {read.begin(), read.end()}, "output", "the render");
  for (const auto& removed : io::prepare_exr_output(output, w))
    std::fprintf(stderr, "note: removed '%s', a partial output left by an earlier run that was killed\n",
                 removed.c_str());
}

// A frame of the sequence read without its reference (a neighbour), or the one already held.
std::shared_ptr<const AovStack> neighbour_stack(FrameContext& context, const std::vector<std::filesystem::path>& files) {
  const std::string key = files.front().string();
  if (const auto it = context.neighbour_frames.find(key); it != context.neighbour_frames.end()) return it->second;
  if (const auto it = context.denoised_frames.find(key); it != context.denoised_frames.end()) return it->second.stack;
  LoadOptions lo = context.options.input.load_options();
  lo.load_reference = false;
  lo.reference.reset();
  auto s = std::make_shared<const AovStack>(load_aov_stack(files, lo));
  context.neighbour_frames[key] = s;
  return s;
}

// Frame t's neighbours warped to it (core/temporal/frame_window.h). Returns the offsets the sequence lacks.
std::vector<int> read_neighbours(FrameContext& context, AovStack& frame, int radius, const NeighbourInputs& inputs) {
  std::map<int, std::shared_ptr<const AovStack>> window;
  for (int d : neighbour_offsets(radius))
    if (const std::optional<std::vector<std::filesystem::path>> files = inputs(d)) window[d] = neighbour_stack(context, *files);
  return attach_neighbours(frame, radius, [&](int d) -> const AovStack* {
    const auto it = window.find(d);
    return it == window.end() ? nullptr : it->second.get();
  });
}

// Frames the window of frame t has moved past are dropped: those not among t - reach .. t + reach.
void keep_window(FrameContext& context, int reach, const NeighbourInputs& inputs, const std::string& self) {
  std::set<std::string> keep = {self};
  for (int d = -reach; d <= reach; ++d)
    if (const auto files = inputs(d)) keep.insert(files->front().string());
  std::erase_if(context.neighbour_frames, [&](const auto& e) { return !keep.count(e.first); });
  std::erase_if(context.denoised_frames, [&](const auto& e) { return !keep.count(e.first); });
}

// --temporal-blend: frame t + offset denoised (before the blend), once per run. `stack`: the frame when it is
// already read (frame t itself), else it is read as a neighbour.
const FrameContext::Denoised& denoised_at(FrameContext& context, const Method& method, const DenoiseOptions& d,
                                          int offset, const std::vector<std::filesystem::path>& files,
                                          std::shared_ptr<AovStack> stack, const NeighbourInputs& inputs,
                                          const TileCallback& on_tile) {
  const std::string key = files.front().string();
  if (const auto it = context.denoised_frames.find(key); it != context.denoised_frames.end()) return it->second;
  FrameContext::Denoised done;
  if (!stack) {  // its own copy, which gets its neighbours attached; held from now on as the denoised frame's
    stack = std::make_shared<AovStack>(*neighbour_stack(context, files));
    context.neighbour_frames.erase(key);
  }
  if (method.frame_radius() > 0)
    done.missing_neighbours = read_neighbours(context, *stack, method.frame_radius(),
                                              [&](int n) { return inputs(offset + n); });
  done.image = std::make_shared<const Image>(denoise(*stack, method, d, on_tile, &done.stats));
  stack->neighbours.clear();
  done.stack = std::move(stack);
  return context.denoised_frames[key] = std::move(done);
}

// Frame t's denoised colour blended with frames t-1 and t+1's along the motion (core/temporal/temporal_blend.h).
Image blended(FrameContext& context, const Method& method, const DenoiseOptions& d,
              const std::vector<std::filesystem::path>& inputs, std::shared_ptr<AovStack> stack,
              const NeighbourInputs& neighbours, const TileCallback& on_tile, FrameResult& result) {
  const FrameContext::Denoised& self = denoised_at(context, method, d, 0, inputs, std::move(stack), neighbours, on_tile);
  result.stats = self.stats;
  result.missing_neighbours = self.missing_neighbours;
  const TileCallback quiet = [&](const TileEvent&, const Image&) { return !context.interrupt.interrupted(); };
  Image out = temporal_blend_frames(*self.stack, *self.image, [&](int offset) -> DenoisedFrame {
    const std::optional<std::vector<std::filesystem::path>> files = neighbours(offset);
    if (!files) {
      result.blend_missing.push_back(offset);
      return {};
    }
    const FrameContext::Denoised& other = denoised_at(context, method, d, offset, *files, nullptr, neighbours, quiet);
    throw_if_cancelled(d.cancel);
    return {other.stack.get(), other.image.get()};
  }, {.tolerance = context.options.blend_tolerance});
  keep_window(context, std::max(1, method.frame_radius()) + 1, neighbours, inputs.front().string());
  return out;
}

}  // namespace

std::string DenoiseCliOptions::model_name() const {
  if (!temporal) return model;
  // A family's temporal model: NAME-temporal (multiscale -> multiscale-temporal); a file or a temporal name as given.
  const std::string suffix = "-temporal";
  const bool named_temporal = model.size() > suffix.size() && model.compare(model.size() - suffix.size(), suffix.size(), suffix) == 0;
  if (named_temporal || std::filesystem::path(model).has_extension()) return model;
  return model + suffix;
}

DenoiseOptions DenoiseCliOptions::denoise_options() const {
  DenoiseOptions d;
  d.backend = backend;
  d.precision = nn::parse_precision(precision);
  d.tile = tile;
  d.threads = threads;
  d.max_memory = max_memory_mib << 20;
  d.skip_empty_tiles = !no_skip;
  d.energy_correction = !no_energy_correction;
  d.variance_blend = !no_variance_blend;
  d.strength = strength;
  d.skip_converged = skip_converged;
  d.ensemble = ensemble;
  if (!roi.empty()) d.roi = parse_roi(roi);
  return d;
}

io::ExrWriteOptions DenoiseCliOptions::write_options() const {
  io::ExrWriteOptions w;
  w.pixel_type = float_output ? io::PixelType::Float : io::PixelType::Half;
  w.compression = compression;
  w.overwrite = force;
  return w;
}

FrameRead read_frame_ahead(const std::vector<std::filesystem::path>& inputs, const LoadOptions& load, size_t max_memory) {
  FrameRead r;
  const auto t0 = std::chrono::steady_clock::now();
  r.reader = std::make_shared<const AovReader>(inputs, load);
  const AovStack& layout = r.reader->layout();
  if (2 * whole_image_bytes(layout) <= max_memory)
    r.stack = std::make_shared<AovStack>(r.reader->read({0, 0, layout.data_window.width, layout.data_window.height}));
  r.read_s = seconds_since(t0);
  return r;
}

FrameToWrite denoise_frame_image(FrameContext& context, const std::vector<std::filesystem::path>& inputs,
                                  const LoadOptions& load, const std::string& output, const NeighbourInputs* neighbours,
                                  std::future<FrameRead>* ahead) {
  const DenoiseCliOptions& o = context.options;
  FrameRead read = ahead ? ahead->get() : FrameRead{std::make_shared<const AovReader>(inputs, load), nullptr, 0};
  const AovReader& reader = *read.reader;
  const AovStack& layout = reader.layout();
  FrameToWrite frame;
  frame.reader = read.reader;
  FrameResult& result = frame.result;
  result.output = output;
  result.notes = layout.notes;
  if (context.show_progress)
    for (const std::string& note : layout.notes) std::fprintf(stderr, "note: %s\n", note.c_str());
  const Rect whole{0, 0, layout.data_window.width, layout.data_window.height};
  DenoiseOptions d = o.denoise_options();
  d.cancel = &context.interrupt.token();
  d.backends = &context.backends;
  frame.roi = d.roi;

  io::ExrWriteOptions& w = frame.write;
  w = o.write_options();
  keep_render_header(w, layout);
  io::record(w.residue_attributes, {.source = layout.color.source.file, .written_by = "residue-cli"});
  check_output(output, layout, w);

  ProgressReporter progress;
  auto on_tile = [&](const TileEvent& e, const Image&) {
    if (context.show_progress) progress.tile(e);
    // Another process may create the output meanwhile: say so now rather than after the work.
    std::error_code ec;
    if (!o.force && std::filesystem::exists(std::filesystem::symlink_status(output, ec)))
      throw Error(ErrorKind::Output, "output '" + output + "' was created by another program during the denoise; "
                                     "nothing was replaced (pass --force to replace it)");
    return !context.interrupt.interrupted();
  };
  DenoiseStats& stats = result.stats;
  // A model name picks the variant trained for the AOVs this render has (NAME, NAME-albedo-normal, NAME-color);
  // each file is loaded once per process.
  const std::unique_ptr<Method> method = resolve_method(o.model_name(), feature_set_for(layout), context.models);
  result.frame_radius = method->frame_radius();
  if (o.temporal && result.frame_radius == 0)
    throw Error(ErrorKind::Usage, "--temporal: " + method->name() + " denoises frames one by one; give a temporal "
                                  "model (" + nn::kDefaultTemporalModel + ", the default with --temporal)");
  if ((result.frame_radius > 0 || o.temporal_blend) && neighbours && !layout.motion)
    throw Error(ErrorKind::Input, "'" + layout.color.source.file + "' has no motion AOV (Cycles: the Vector pass; "
                                  "another renderer's: --map motion=...): " +
                                      (result.frame_radius > 0 ? method->name() : std::string("--temporal-blend")) +
                                  " warps the neighbouring frames to it along the motion vectors");
  result.model = method->name();
  result.architecture = method->architecture();
  io::record(w.residue_attributes, {.model = result.model, .architecture = result.architecture});
  // Renders that fit in --max-memory are denoised in memory; larger ones band by band from and to the files
  // (then the header cannot carry the time, which is known only at the end).
  // (The temporal blend holds frames t-1..t+1 whole: it does not stream.)
  result.streamed = method->streams() && whole_image_bytes(layout) > d.max_memory && !(o.temporal_blend && neighbours);
  if (result.streamed && o.skip_converged > 0)
    throw Error(ErrorKind::Usage, "--skip-converged needs the render in memory, and '" + layout.color.source.file + "' (" +
                                      std::to_string(whole_image_bytes(layout) >> 20) + " MiB as float) is more than "
                                      "--max-memory " + std::to_string(o.max_memory_mib) + ": raise --max-memory to hold it");
  if (result.streamed) {  // the header, written first, says which post-steps run (core decides, as below)
    stats = denoise_to_exr(reader, *method, d, output, w, on_tile);
  } else {
    const auto t0 = std::chrono::steady_clock::now();
    const double read_ahead_s = read.stack ? read.read_s : 0.0;
    auto stack = read.stack ? std::move(read.stack) : std::make_shared<AovStack>(reader.read(whole));
    const bool blend = o.temporal_blend && neighbours;
    if (result.frame_radius > 0 && neighbours && !blend)
      result.missing_neighbours = read_neighbours(context, *stack, result.frame_radius, *neighbours);
    result.read_s = read_ahead_s + seconds_since(t0);
    Image out = blend ? blended(context, *method, d, inputs, stack, *neighbours, on_tile, result)
                      : denoise(*stack, *method, d, on_tile, &stats);
    if (result.frame_radius > 0 && neighbours && !blend) {  // the next frames read this one as a neighbour
      stack->neighbours.clear();
      context.neighbour_frames[layout.color.source.file] = stack;
      keep_window(context, result.frame_radius, *neighbours, layout.color.source.file);
    }
    throw_if_cancelled(d.cancel);
    io::record(w.residue_attributes, provenance_of(*method, stats));
    if (blend) io::record(w.residue_attributes, {.temporal_blend = static_cast<float>(o.blend_tolerance)});
    frame.image = std::move(out);
  }
  result.megapixels = static_cast<double>(d.roi ? d.roi->area() : whole.area()) / 1e6;
  return frame;
}

FrameResult write_frame(FrameToWrite frame, const CancelToken& cancel) {
  FrameResult& result = frame.result;
  const std::string& output = result.output;
  if (frame.image) {
    const auto t0 = std::chrono::steady_clock::now();
    result.stats.clamped_to_half = io::write_exr(output, *frame.image, frame.write).clamped_to_half;
    result.write_s = seconds_since(t0);
    frame.image.reset();
  }
  const AovReader& reader = *frame.reader;
  const AovStack& layout = reader.layout();
  if (layout.reference && !cancel.requested()) {
    // Scored from the file written, as the user will see it, band by band (the noisy input, the output and the
    // reference are never whole in memory: the streamed denoise's --max-memory holds here too).
    const Rect whole{0, 0, layout.data_window.width, layout.data_window.height};
    metrics::Options m;
    m.roi = frame.roi;
    LoadOptions lo;
    lo.load_reference = false;
    const AovReader written({output}, lo);
    metrics::ScoreAccumulator noisy(whole.width, whole.height, m), denoised(whole.width, whole.height, m);
    const Rect region = noisy.region();
    constexpr int64_t kBand = 4 * metrics::ScoreAccumulator::kRowMultiple;
    for (int64_t y0 = region.y; y0 < region.y + region.height; y0 += kBand) {
      if (cancel.requested()) return std::move(result);  // the output is whole: only its scores are left out
      const int64_t y1 = std::min(y0 + kBand, region.y + region.height);
      const int64_t r0 = std::max<int64_t>(0, y0 - metrics::ScoreAccumulator::kHalo);
      const int64_t r1 = std::min(whole.height, y1 + metrics::ScoreAccumulator::kHalo);
      const Rect rows{0, r0, whole.width, r1 - r0};
      const AovStack in = reader.read(rows);
      const AovStack out = written.read(rows);
      noisy.add(in.color.image, in.reference->image, r0, y0, y1);
      denoised.add(out.color.image, in.reference->image, r0, y0, y1);
    }
    io::MetricsReport report{layout.reference->source.file, whole.width, whole.height, m, {}, layout.notes};
    report.rows.push_back({"noisy", layout.color.source.file, noisy.scores()});
    report.rows.push_back({"denoised", output, denoised.scores()});
    result.metrics = std::move(report);
  }
  return std::move(result);
}

FrameResult denoise_frame(FrameContext& context, const std::vector<std::filesystem::path>& inputs,
                          const LoadOptions& load, const std::string& output, const NeighbourInputs* neighbours) {
  return write_frame(denoise_frame_image(context, inputs, load, output, neighbours), context.interrupt.token());
}

}  // namespace residue::cli
