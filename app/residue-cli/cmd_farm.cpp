// residue-cli farm: a frame sequence denoised on a render farm.
//
//   farm slurm IN.####.exr -o OUT.####.exr -m MODEL [--frames SPEC] [--chunk 10] [--retries 2] [--job-dir DIR]
//       writes DIR/chunks.txt (one frame spec per array task), DIR/denoise.sbatch (a job array: task i runs
//       `residue-cli denoise --frames <line i> --skip-existing --summary DIR/chunk_i.json`, retrying a failed
//       chunk; finished frames are skipped, never redone) and DIR/gather.sbatch (runs after the array, whatever
//       its result, and gathers the chunks' JSON), then submits both with sbatch (--dry-run: writes only).
//   farm gather DIR
//       merges DIR/chunk_*.json into DIR/summary.json; exit 0 when every frame was denoised or skipped.
// Any scheduler works the same way: one task = one chunk = one `residue-cli denoise --frames ... --skip-existing`
// (docs/FARM.md).
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>

#include "cli_common.h"
#include "commands.h"
#include "core/denoise/method_registry.h"
#include "core/aov/aov_loader.h"
#include "core/features/features.h"
#include "core/io/atomic_file.h"
#include "core/io/frame_sequence.h"
#include "core/nn/model_card.h"
#include "core/nn/model_file.h"
#include "core/nn/model_registry.h"
#include "core/util/error.h"

namespace residue::cli {
namespace {

namespace fs = std::filesystem;

struct FarmOptions {
  std::string input, output, reference, model, frames, job_dir = "residue-farm", partition;
  int64_t chunk = 10;
  int retries = 2, max_parallel = 0, cpus = 2;
  bool dry_run = false;
  bool temporal = false;  // each frame with its neighbours (denoise --temporal); a chunk reads the frames beside it
  bool temporal_blend = false;  // denoise --temporal-blend; likewise
  std::vector<std::string> denoise_args;  // passed through to each denoise
};

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string self_path() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("residue-cli") : p.string();
}

// Frames as a compact spec: runs of consecutive frames as "a-b".
std::string spec_of(const std::vector<int64_t>& frames) {
  std::string s;
  for (size_t i = 0; i < frames.size();) {
    size_t j = i;
    while (j + 1 < frames.size() && frames[j + 1] == frames[j] + 1) ++j;
    s += (s.empty() ? "" : ",") + std::to_string(frames[i]) + (j > i ? "-" + std::to_string(frames[j]) : "");
    i = j + 1;
  }
  return s;
}

void write_text(const fs::path& path, const std::string& text, bool executable) {
  io::write_atomically(path, true, [&](const fs::path& temp) {
    std::ofstream f(temp, std::ios::binary);
    f << text;
    if (!f.flush()) throw Error(ErrorKind::Output, "cannot write '" + path.string() + "'");
  });
  if (executable) fs::permissions(path, fs::perms::owner_exec | fs::perms::group_exec, fs::perm_options::add);
}

// Runs `command`, returns its stdout; Error(Output) naming it when it fails.
std::string run_command(const std::string& command) {
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) throw Error(ErrorKind::Output, "cannot run " + command);
  std::string out;
  char buf[4096];
  size_t n = 0;
  while ((n = fread(buf, 1, sizeof buf, pipe)) > 0) out.append(buf, n);
  const int status = pclose(pipe);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw Error(ErrorKind::Output, "`" + command + "` failed: " + out);
  while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
  return out;
}

// What goes into an #SBATCH line verbatim is checked: a newline would start another directive.
void check_job_options(const FarmOptions& o) {
  const auto control = [](const std::string& s) {
    return std::any_of(s.begin(), s.end(), [](unsigned char c) { return c < 0x20 || c == 0x7f; });
  };
  if (!o.partition.empty() &&
      !std::all_of(o.partition.begin(), o.partition.end(), [](unsigned char c) { return std::isalnum(c) || c == '_' || c == '-' || c == '.' || c == ','; }))
    throw Error(ErrorKind::Usage, "--partition '" + o.partition + "': a Slurm partition name (letters, digits, _ - . and "
                                  "commas between several)");
  if (control(o.job_dir)) throw Error(ErrorKind::Usage, "--job-dir: a folder name without newlines or control characters");
}

// Slurm expands %-patterns in --output file names: a literal % is written %%.
std::string slurm_file_name(const std::string& path) {
  std::string s;
  for (char c : path) s += c == '%' ? std::string("%%") : std::string(1, c);
  return s;
}

// The model must resolve for the frames' AOVs now, not fail on every task once the array runs.
std::string model_of(const FarmOptions& o) {
  return o.model.empty() ? nn::kDefaultTemporalModel : o.model;
}

void check_model(const FarmOptions& o, const fs::path& first_frame) {
  if (o.model.empty() && !o.temporal) throw Error(ErrorKind::Usage, "farm slurm: give -m MODEL (or --temporal)");
  if (is_model_free_method(model_of(o))) {
    if (o.temporal) throw Error(ErrorKind::Usage, "--temporal runs a temporal network, not the " + o.model + " filter");
    return;
  }
  const AovReader reader({first_frame}, LoadOptions{});
  if ((o.temporal || o.temporal_blend) && !reader.layout().motion)
    throw Error(ErrorKind::Input, "'" + first_frame.string() + "' has no motion AOV (Cycles: the Vector pass): " +
                                      (o.temporal ? "--temporal" : "--temporal-blend") +
                                      " warps each frame's neighbours to it along the motion vectors");
  (void)nn::find_model_for(model_of(o), feature_set_for(reader.layout()));
}

int run_slurm(const FarmOptions& o) {
  check_job_options(o);
  const auto in = io::FramePattern::parse(o.input);
  const auto out = io::FramePattern::parse(o.output);
  if (!in || !out) throw Error(ErrorKind::Usage, "farm: give the input and -o as frame patterns (shot.####.exr)");
  const std::vector<int64_t> frames = o.frames.empty() ? io::find_frames(*in) : io::parse_frame_spec(o.frames);
  if (frames.empty()) throw Error(ErrorKind::Input, "no frame of '" + in->to_string() + "' exists (give --frames)");
  std::vector<int64_t> present;
  for (int64_t f : frames)
    if (std::error_code ec; fs::is_regular_file(in->path(f), ec)) present.push_back(f);
  if (present.empty())
    throw Error(ErrorKind::Input, "none of the " + std::to_string(frames.size()) + " frames asked for exists (" +
                                      in->path(frames.front()).string() + ", ...)");
  if (present.size() < frames.size())
    std::fprintf(stderr, "note: %zu of the %zu frames have no input yet (%s, ...); their tasks will report them\n",
                 frames.size() - present.size(), frames.size(), in->path(frames.front()).c_str());
  check_model(o, in->path(present.front()));
  const fs::path dir = fs::absolute(o.job_dir);
  if (std::error_code ec; fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw Error(ErrorKind::Output, "--job-dir '" + dir.string() + "' is a file, not a folder");
  fs::create_directories(dir / "logs");
  // An earlier submission's chunk summaries would be merged by the gather with this one's (its chunking may
  // differ): they go; the frames it finished stay and are skipped.
  int stale = 0;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if ((name.rfind("chunk_", 0) == 0 && it->path().extension() == ".json") || name == "summary.json")
      stale += fs::remove(it->path(), ec) ? 1 : 0;
  }
  if (stale > 0) std::printf("note       removed %d summaries of an earlier submission in %s\n", stale, dir.c_str());

  std::string chunks;
  int64_t tasks = 0;
  for (size_t i = 0; i < frames.size(); i += static_cast<size_t>(o.chunk), ++tasks)
    chunks += spec_of({frames.begin() + static_cast<std::ptrdiff_t>(i),
                       frames.begin() + static_cast<std::ptrdiff_t>(std::min(frames.size(), i + static_cast<size_t>(o.chunk)))}) + "\n";
  write_text(dir / "chunks.txt", chunks, false);

  std::string denoise = quote(self_path()) + " denoise " + quote(fs::absolute(o.input).string()) + " -o " +
                        quote(fs::absolute(o.output).string()) + " -m " + quote(model_of(o)) + " --threads " +
                        std::to_string(o.cpus) + " --skip-existing" + (o.temporal ? " --temporal" : "") +
                        (o.temporal_blend ? " --temporal-blend" : "");
  if (!o.reference.empty()) denoise += " -r " + quote(fs::absolute(o.reference).string());
  for (const std::string& a : o.denoise_args) denoise += " " + quote(a);
  std::ostringstream task;
  task << "#!/bin/bash\n"
       << "# Written by residue-cli farm slurm: one array task per line of chunks.txt.\n"
       << "#SBATCH --job-name=residue-denoise\n"
       << "#SBATCH --array=0-" << tasks - 1 << (o.max_parallel > 0 ? "%" + std::to_string(o.max_parallel) : "") << "\n"
       << "#SBATCH --cpus-per-task=" << o.cpus << "\n"
       << "#SBATCH --output=" << slurm_file_name((dir / "logs").string()) << "/chunk_%a.log\n"
       << (o.partition.empty() ? "" : "#SBATCH --partition=" + o.partition + "\n")
       << "set -u\n"
       << "frames=$(sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" " << quote((dir / "chunks.txt").string()) << ")\n"
       << "summary=" << quote(dir.string()) << "/chunk_${SLURM_ARRAY_TASK_ID}.json\n"
       << "rc=1\n"
       << "for attempt in $(seq 1 " << o.retries + 1 << "); do\n"
       << "  " << denoise << " --frames \"$frames\" --summary \"$summary\"\n"
       << "  rc=$?\n"
       << "  if [ $rc -eq 0 ] || [ $rc -eq 130 ] || [ $rc -eq 143 ]; then exit $rc; fi  # done, or cancelled\n"
       << "  echo \"chunk ${SLURM_ARRAY_TASK_ID} (frames $frames): attempt $attempt failed with exit $rc\" >&2\n"
       << "done\n"
       << "exit $rc\n";
  write_text(dir / "denoise.sbatch", task.str(), true);
  std::ostringstream gather;
  gather << "#!/bin/bash\n"
         << "# Written by residue-cli farm slurm: runs after the array (whatever its tasks' results).\n"
         << "#SBATCH --job-name=residue-gather\n"
         << "#SBATCH --cpus-per-task=1\n"
         << "#SBATCH --output=" << slurm_file_name((dir / "logs/gather.log").string()) << "\n"
         << (o.partition.empty() ? "" : "#SBATCH --partition=" + o.partition + "\n")
         << quote(self_path()) << " farm gather " << quote(dir.string()) << "\n";
  write_text(dir / "gather.sbatch", gather.str(), true);
  std::printf("job dir    %s\nframes     %zu in %lld chunks of up to %lld (retries %d)\n", dir.c_str(), frames.size(),
              static_cast<long long>(tasks), static_cast<long long>(o.chunk), o.retries);
  if (o.dry_run) {
    std::printf("dry run    submit with: sbatch --parsable %s, then sbatch --dependency=afterany:JOBID %s\n",
                (dir / "denoise.sbatch").c_str(), (dir / "gather.sbatch").c_str());
    return kOk;
  }
  const std::string array_id = run_command("sbatch --parsable " + quote((dir / "denoise.sbatch").string()));
  const std::string job = array_id.substr(0, array_id.find(';'));
  const std::string gather_id =
      run_command("sbatch --parsable --dependency=afterany:" + job + " " + quote((dir / "gather.sbatch").string()));
  write_text(dir / "jobs.json", nlohmann::json{{"array", job}, {"gather", gather_id.substr(0, gather_id.find(';'))}}.dump() + "\n", false);
  std::printf("submitted  array job %s, gather job %s (summary: %s)\n", job.c_str(), gather_id.c_str(),
              (dir / "summary.json").c_str());
  return kOk;
}

int run_gather(const std::string& job_dir) {
  const fs::path dir(job_dir);
  std::ifstream chunks_file(dir / "chunks.txt");
  if (!chunks_file) throw Error(ErrorKind::Input, "'" + (dir / "chunks.txt").string() + "' is missing: not a farm job folder");
  std::vector<std::string> chunks;
  for (std::string line; std::getline(chunks_file, line);) chunks.push_back(line);
  nlohmann::ordered_json frames = nlohmann::ordered_json::array();
  int done = 0, skipped = 0, failed = 0, exit_code = kOk;
  std::vector<std::string> missing;
  double denoise_seconds = 0, megapixels = 0;
  for (size_t i = 0; i < chunks.size(); ++i) {
    const fs::path p = dir / ("chunk_" + std::to_string(i) + ".json");
    std::ifstream f(p);
    if (!f) {
      missing.push_back(std::to_string(i) + " (frames " + chunks[i] + ")");
      continue;
    }
    nlohmann::ordered_json j;
    try {
      j = nlohmann::ordered_json::parse(f);
    } catch (const std::exception& e) {
      throw Error(ErrorKind::Input, "'" + p.string() + "' is not a chunk summary: " + e.what());
    }
    for (auto& frame : j["frames"]) {
      const std::string status = frame.value("status", "");
      done += status == "done";
      skipped += status == "skipped";
      failed += status != "done" && status != "skipped";
      if (status == "done") {
        denoise_seconds += frame.value("seconds", 0.0);
        megapixels += frame.value("megapixels", 0.0);
      }
      frames.push_back(frame);
    }
    if (exit_code == kOk && j.value("exit_code", 0) != 0) exit_code = j.value("exit_code", 1);
  }
  if (exit_code == kOk && !missing.empty()) exit_code = kInternalError;
  nlohmann::ordered_json doc{{"chunks", chunks.size()}, {"chunks_missing", missing}, {"done", done}, {"skipped", skipped},
                             {"failed", failed}, {"s_per_mp", megapixels > 0 ? denoise_seconds / megapixels : 0.0},
                             {"exit_code", exit_code}, {"frames", frames}};
  write_text(dir / "summary.json", doc.dump(1) + "\n", false);
  std::printf("frames     %d done, %d skipped, %d failed; %zu of %zu chunks reported\nsummary    %s\n", done, skipped,
              failed, chunks.size() - missing.size(), chunks.size(), (dir / "summary.json").c_str());
  for (const auto& m : missing) std::fprintf(stderr, "chunk %s left no summary: see its log in logs/\n", m.c_str());
  return exit_code;
}

}  // namespace

Command add_farm_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("farm", "Denoise a frame sequence on a render farm (Slurm job arrays)");
  cmd->require_subcommand(1);
  auto o = std::make_shared<FarmOptions>();
  auto* slurm = cmd->add_subcommand("slurm", "Write and submit a Slurm job array: one task per chunk of frames, then a "
                                             "job that gathers the chunks' summaries");
  slurm->add_option("input", o->input, "The noisy frames, a pattern: shot.####.exr")->required();
  slurm->add_option("-o,--output", o->output, "The denoised frames, a pattern: out.####.exr")->required();
  slurm->add_option("-m,--model", o->model, "The model (as for denoise; with --temporal, default " +
                    std::string(nn::kDefaultTemporalModel) + ")");
  slurm->add_flag("--temporal", o->temporal, "Denoise each frame with its neighbours (denoise --temporal): each task "
                  "reads the frames beside its chunk, so frames come out as one run over the whole range makes them");
  slurm->add_flag("--temporal-blend", o->temporal_blend, "Blend each frame with frames t-1 and t+1 along the motion "
                  "(denoise --temporal-blend): each task reads and denoises the frames beside its chunk too");
  slurm->add_option("-r,--reference", o->reference, "References, a pattern (ref.####.exr): per-frame metrics");
  slurm->add_option("--frames", o->frames, "Frames, e.g. 1001-1100 (default: every frame whose input exists now)");
  slurm->add_option("--chunk", o->chunk, "Frames per array task")->capture_default_str()->check(CLI::Range(1, 1 << 20));
  slurm->add_option("--retries", o->retries, "Reruns of a chunk that fails (finished frames are skipped)")
      ->capture_default_str()
      ->check(CLI::Range(0, 10));
  slurm->add_option("--job-dir", o->job_dir, "Folder for the scripts, chunk summaries and logs")->capture_default_str();
  slurm->add_option("--partition", o->partition, "Slurm partition (default: the cluster's)");
  slurm->add_option("--max-parallel", o->max_parallel, "At most this many tasks at once (0: no limit)")
      ->check(CLI::Range(0, 1 << 20));
  slurm->add_option("--cpus-per-task", o->cpus, "Cores per task (the denoise's --threads)")->capture_default_str()->check(CLI::Range(1, 1024));
  slurm->add_flag("--dry-run", o->dry_run, "Write the scripts without submitting them");
  slurm->add_option("--denoise-arg", o->denoise_args, "An argument passed to each denoise (repeat: --denoise-arg=--float)");
  auto gather_dir = std::make_shared<std::string>();
  auto* gather = cmd->add_subcommand("gather", "Merge a farm job's chunk summaries into summary.json");
  gather->add_option("job_dir", *gather_dir, "The job folder")->required();
  return {cmd, [o, slurm, gather_dir]() { return slurm->parsed() ? run_slurm(*o) : run_gather(*gather_dir); }};
}

}  // namespace residue::cli
