#include "denoise_sequence.h"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include <nlohmann/json.hpp>

#include "background_io.h"
#include "core/io/atomic_file.h"
#include "core/io/frame_claim.h"
#include "core/io/frame_sequence.h"
#include "core/util/error.h"

namespace residue::cli {
namespace {

namespace fs = std::filesystem;
using io::FramePattern;

struct FrameRecord {
  int64_t frame = 0;
  fs::path input, output;
  std::string status = "pending";  // done, skipped, failed, interrupted, pending (not reached)
  std::string error;
  std::string note;  // why a frame was skipped or redone
  int exit_code = kOk;
  double seconds = 0, megapixels = 0;
  std::string model;
  std::optional<io::MetricsReport> metrics;
  std::vector<int> missing_neighbours;  // a temporal method's: offsets the sequence lacked
  std::vector<int> blend_missing;       // --temporal-blend's: offsets of -1, +1 the sequence lacked
};

FramePattern pattern_of(const std::string& text, const char* what) {
  std::optional<FramePattern> p = FramePattern::parse(text);
  if (!p)
    throw Error(ErrorKind::Usage, std::string(what) + " '" + text + "' names no frame: for a sequence give a pattern "
                                  "such as out.####.exr or out.%04d.exr");
  return *p;
}

// On a farm (a Slurm task) a rerun of a chunk must not redo or refuse finished frames.
bool on_farm() { return std::getenv("SLURM_ARRAY_TASK_ID") != nullptr || std::getenv("SLURM_JOB_ID") != nullptr; }

nlohmann::ordered_json to_json(const std::vector<FrameRecord>& records, const DenoiseCliOptions& o,
                               const FramePattern& in, const FramePattern& out, double seconds, int exit_code) {
  nlohmann::ordered_json frames = nlohmann::ordered_json::array();
  int done = 0, skipped = 0, failed = 0;
  double megapixels = 0, denoise_seconds = 0;
  for (const FrameRecord& r : records) {
    nlohmann::ordered_json j{{"frame", r.frame}, {"input", r.input.string()}, {"output", r.output.string()}, {"status", r.status}};
    if (!r.error.empty()) j["error"] = r.error;
    if (!r.note.empty()) j["note"] = r.note;
    if (r.status == "done") {
      j["model"] = r.model;
      j["seconds"] = r.seconds;
      j["megapixels"] = r.megapixels;
      if (!r.missing_neighbours.empty()) j["missing_neighbours"] = r.missing_neighbours;
      if (!r.blend_missing.empty()) j["blend_missing"] = r.blend_missing;
      if (r.metrics) {
        const auto& noisy = r.metrics->rows[0].scores;
        const auto& denoised = r.metrics->rows[1].scores;
        j["reference"] = r.metrics->reference_file;
        j["relmse"] = denoised.relmse;
        j["ssim"] = denoised.ssim;
        j["noisy_relmse"] = noisy.relmse;
        j["noisy_ssim"] = noisy.ssim;
      }
      ++done;
      megapixels += r.megapixels;
      denoise_seconds += r.seconds;
    }
    skipped += r.status == "skipped";
    failed += r.status == "failed";
    frames.push_back(std::move(j));
  }
  nlohmann::ordered_json doc;
  doc["input"] = in.to_string();
  doc["output"] = out.to_string();
  doc["model"] = o.model_name();
  if (o.temporal_blend) doc["temporal_blend"] = {{"frames", "t-1..t+1"}, {"tolerance", o.blend_tolerance}};
  doc["frames_requested"] = records.size();
  doc["done"] = done;
  doc["skipped"] = skipped;
  doc["failed"] = failed;
  doc["seconds"] = seconds;
  doc["s_per_mp"] = megapixels > 0 ? denoise_seconds / megapixels : 0.0;
  doc["exit_code"] = exit_code;
  doc["frames"] = std::move(frames);
  return doc;
}

// A denoised frame's line: its output, time, scores and missing neighbours, [index/total].
void print_done(const FrameRecord& r, size_t index, size_t total) {
  std::printf("frame %lld  %s  %.2f s (%.2f s/MP)", static_cast<long long>(r.frame), display_path(r.output.string()).c_str(),
              r.seconds, r.seconds / std::max(r.megapixels, 1e-9));
  if (r.metrics)
    std::printf("  relMSE %.5f (noisy %.5f)  SSIM %.4f", r.metrics->rows[1].scores.relmse, r.metrics->rows[0].scores.relmse,
                r.metrics->rows[1].scores.ssim);
  if (!r.missing_neighbours.empty()) {
    std::string missing;
    for (int d : r.missing_neighbours) missing += (missing.empty() ? "" : ", ") + std::string(d < 0 ? "t" : "t+") + std::to_string(d);
    std::printf("  (fewer neighbours: no frame %s)", missing.c_str());
  }
  if (r.blend_missing.size() == 2) std::printf("  (no frame beside it to blend with)");
  else if (!r.blend_missing.empty()) std::printf("  (blended with frame %s only)", r.blend_missing.front() < 0 ? "t+1" : "t-1");
  std::printf("  [%zu/%zu]\n", index, total);
  std::fflush(stdout);
}

}  // namespace

bool is_sequence(const DenoiseCliOptions& o) {
  return o.input.inputs.size() == 1 && FramePattern::parse(o.input.inputs.front()).has_value();
}

int run_sequence(const DenoiseCliOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  const FramePattern in = pattern_of(o.input.inputs.front(), "input");
  const FramePattern out = pattern_of(o.output, "output -o");
  const std::optional<FramePattern> reference =
      o.input.reference.empty() ? std::nullopt : std::optional(pattern_of(o.input.reference, "reference -r"));
  const bool skip_existing = !o.force && (o.skip_existing || on_farm());

  std::vector<int64_t> frames = o.frames.empty() ? io::find_frames(in) : io::parse_frame_spec(o.frames);
  if (frames.empty())
    throw Error(ErrorKind::Input, "no frame of '" + in.to_string() + "' exists (give --frames to name them)");

  // --temporal and --temporal-blend warp each frame's neighbours along its motion vectors: a sequence without them
  // is refused now.
  if (o.temporal || o.temporal_blend)
    for (int64_t f : frames)
      if (fs::exists(in.path(f))) {
        const AovReader first({in.path(f)}, o.input.load_options());
        if (!first.layout().motion)
          throw Error(ErrorKind::Input, std::string(o.temporal ? "--temporal" : "--temporal-blend") + ": '" +
                                            in.path(f).string() + "' has no motion AOV (Cycles: the "
                                        "Vector pass; another renderer's: --map motion=...): the neighbouring frames "
                                        "are warped to each frame along its motion vectors");
        break;
      }
  // Every check before the first frame: the summary file, then each output (a conflict lists them all).
  if (!o.summary.empty()) {
    io::require_extension(o.summary, {".json"}, "--summary");
    std::vector<fs::path> read = o.input.files_named();
    for (int64_t f : frames) {
      read.push_back(in.path(f));
      read.push_back(out.path(f));  // written, and so not to be replaced by the summary either
      if (reference) read.push_back(reference->path(f));
    }
    io::refuse_input_as_output(o.summary, read, "--summary");
    io::prepare_output(o.summary, o.force || skip_existing);
  }
  std::vector<FrameRecord> records;
  std::vector<std::string> existing;
  const io::ExrWriteOptions w = o.write_options();
  for (int64_t f : frames) {
    FrameRecord r;
    r.frame = f;
    r.input = in.path(f);
    r.output = out.path(f);
    std::error_code ec;
    if (fs::exists(fs::symlink_status(r.output, ec)) && !o.force) {
      if (!skip_existing) existing.push_back(r.output.string());
      else if (const io::ExistingOutput e = io::inspect_output(r.output); e == io::ExistingOutput::Damaged)
        r.note = "damaged";  // redone (below)
      else {
        r.status = "skipped", r.note = e == io::ExistingOutput::Foreign ? "exists, not an OpenEXR file: left alone" : "exists";
        if (e == io::ExistingOutput::Complete) io::FrameClaim::clear_stale(r.output);
      }
    }
    records.push_back(std::move(r));
  }
  if (!existing.empty())
    throw Error(ErrorKind::Output, std::to_string(existing.size()) + " of the " + std::to_string(frames.size()) +
                                       " outputs exist (" + existing.front() + (existing.size() > 1 ? ", ..." : "") +
                                       "); pass --skip-existing to resume, or --force to replace them");
  for (FrameRecord& r : records)
    if (r.status == "pending" && r.note.empty())
      for (const auto& removed : io::prepare_exr_output(r.output, w))
        std::fprintf(stderr, "note: removed '%s', a partial output left by an earlier run that was killed\n", removed.c_str());

  const InterruptScope interrupt;
  FrameContext context{o, interrupt, false};
  int exit_code = kOk;
  const auto load_for = [&](const FrameRecord& r) {
    LoadOptions load = o.input.load_options();
    if (reference) load.reference = reference->path(r.frame);
    return load;
  };
  // A temporal method's neighbours: the frames beside this one on disk, whatever --frames selects.
  const auto neighbours_of = [&](const FrameRecord& r) -> NeighbourInputs {
    return [&in, frame = r.frame](int d) -> std::optional<std::vector<fs::path>> {
      const fs::path p = in.path(frame + d);
      if (!fs::exists(p)) return std::nullopt;
      return std::vector<fs::path>{p};
    };
  };
  const auto failed = [&](FrameRecord& r, const Error& e) {
    r.status = "failed";
    r.error = e.what();
    r.exit_code = exit_code_for(e.kind());
    std::fprintf(stderr, "frame %lld  failed: %s\n", static_cast<long long>(r.frame), e.what());
    if (exit_code == kOk) exit_code = r.exit_code;
  };

  // While frame n is denoised, frame n-1 is written (and scored) and the next frame to denoise is read
  // (background_io.h). A temporal method reads its neighbours as it goes, so its frames are not read ahead.
  const bool read_ahead = !o.temporal && !o.temporal_blend;
  struct Ahead {
    size_t index;
    std::future<FrameRead> read;
  };
  struct Writing {
    size_t index;
    std::future<FrameResult> result;
    std::optional<io::FrameClaim> claim;  // held until the frame is written
  };
  std::optional<Ahead> ahead;
  std::optional<Writing> writing;
  BackgroundIo background;  // after what its tasks use; joined first

  // The frame being written finished: its line printed in order, its record filled. False when the run stops.
  const auto finish_writing = [&]() -> bool {
    if (!writing) return true;
    FrameRecord& r = records[writing->index];
    const size_t index = writing->index;
    bool go_on = true;
    try {
      const FrameResult result = writing->result.get();
      r.missing_neighbours = result.missing_neighbours;
      r.blend_missing = result.blend_missing;
      r.status = "done";
      r.seconds = result.stats.seconds;
      r.megapixels = result.megapixels;
      r.model = result.model;
      r.metrics = result.metrics;
      print_done(r, index + 1, records.size());
    } catch (const Cancelled&) {
      r.status = "interrupted";
      go_on = false;
    } catch (const Error& e) {
      failed(r, e);
      go_on = !o.fail_fast;
    }
    writing.reset();  // the claim ends
    return go_on;
  };

  for (size_t i = 0; i < records.size(); ++i) {
    FrameRecord& r = records[i];
    if (r.status != "skipped" && interrupt.interrupted()) break;
    // Why a frame is not denoised (or is redone), said after the frame before it is written, in order.
    std::string line;
    // Claimed while it is denoised, so that another process on this sequence moves on to the next frame; a frame
    // it finished meanwhile counts as skipped.
    std::optional<io::FrameClaim> claim = r.status == "skipped" ? std::nullopt : io::FrameClaim::take(r.output);
    if (r.status == "skipped") {
      line = "skipped: " + display_path(r.output.string()) + " exists" +
             (r.note != "exists" ? " (not an OpenEXR file: left alone)" : "");
    } else if (!claim) {
      r.status = "skipped", r.note = "claimed by another process";
      line = "skipped: another process is denoising it";
    } else if (std::error_code ec; fs::exists(fs::symlink_status(r.output, ec)) && !o.force) {
      if (io::inspect_output(r.output) != io::ExistingOutput::Damaged) {
        r.status = "skipped", r.note = "finished by another process";
        line = "skipped: " + display_path(r.output.string()) + " was finished by another process";
      } else if (!skip_existing) {  // appeared since the checks: not ours to replace
        r.status = "failed";
        r.error = "output '" + r.output.string() + "' appeared during the run; pass --force to replace it";
      } else {
        line = "re-doing damaged frame: " + display_path(r.output.string()) + " is cut short or empty";
        r.note = "damaged output redone";
        fs::remove(r.output, ec);
      }
    }
    if ((!line.empty() || r.status == "failed") && !finish_writing()) break;
    if (!line.empty()) {
      std::printf("frame %lld  %s\n", static_cast<long long>(r.frame), line.c_str());
      std::fflush(stdout);
    }
    if (r.status == "failed") {
      failed(r, Error(ErrorKind::Output, r.error));
      if (o.fail_fast) break;
      continue;
    }
    if (r.status != "pending") continue;

    const LoadOptions load = load_for(r);
    const NeighbourInputs neighbours = neighbours_of(r);
    try {
      if (!fs::exists(r.input)) throw Error(ErrorKind::Input, "input '" + r.input.string() + "' does not exist");
      std::optional<std::future<FrameRead>> mine;
      if (ahead && ahead->index == i) mine = std::move(ahead->read);
      ahead.reset();
      if (read_ahead)  // the next frame to denoise, read while this one is
        for (size_t n = i + 1; n < records.size(); ++n)
          if (records[n].status == "pending") {
            if (fs::exists(records[n].input))
              ahead = Ahead{n, background.submit([inputs = std::vector<fs::path>{records[n].input}, next = load_for(records[n]),
                                                  max_memory = o.denoise_options().max_memory] {
                return read_frame_ahead(inputs, next, max_memory);
              })};
            break;
          }
      FrameToWrite denoised =
          denoise_frame_image(context, {r.input}, load, r.output.string(), &neighbours, mine ? &*mine : nullptr);
      if (!finish_writing()) break;
      writing.emplace(Writing{i, background.submit([frame = std::make_shared<FrameToWrite>(std::move(denoised)), &interrupt] {
                          return write_frame(std::move(*frame), interrupt.token());
                        }),
                        std::move(claim)});
    } catch (const Cancelled&) {
      r.status = "interrupted";
      break;
    } catch (const Error& e) {
      const bool go_on = finish_writing();
      failed(r, e);
      if (!go_on || o.fail_fast) break;
    }
  }
  finish_writing();
  ahead.reset();
  if (interrupt.interrupted()) exit_code = interrupt.exit_code();

  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const nlohmann::ordered_json summary = to_json(records, o, in, out, seconds, exit_code);
  std::printf("\nframes     %d done, %d skipped, %d failed of %zu%s in %.1f s (%.3f s per megapixel denoising)\n",
              summary["done"].get<int>(), summary["skipped"].get<int>(), summary["failed"].get<int>(), records.size(),
              interrupt.interrupted() ? ", interrupted" : "", seconds, summary["s_per_mp"].get<double>());
  if (!o.summary.empty()) {
    const std::string text = summary.dump(1, ' ', false, nlohmann::ordered_json::error_handler_t::replace) + "\n";
    io::write_atomically(o.summary, true, [&](const fs::path& temp) {
      std::ofstream file(temp, std::ios::binary);
      file << text;
      if (!file.flush()) throw Error(ErrorKind::Output, "cannot write '" + o.summary + "'");
    });
    std::printf("summary    %s\n", display_path(o.summary).c_str());
  }
  return exit_code;
}

}  // namespace residue::cli
