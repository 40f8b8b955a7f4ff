// Result: one denoised image the viewer keeps, so that any two can be compared. A result is either a run of a
// model in the viewer (its settings are its key: asking for them again shows it without a new run), an image
// the user added from a file (another denoiser's output, a colleague's render), or another result at a strength
// below 1 (core/denoise/strength.h: blended towards the noisy colour, "oidn fp32 @ 50 %"), kept beside it. The
// Session owns the list.
#pragma once

#include <QString>
#include <memory>
#include <vector>

#include "core/image/image.h"
#include "core/io/provenance.h"

namespace residue::ui {

// Where a run stands; a result read from a file is Done.
enum class RunState { Done, Running, Cancelled, Failed };

struct Result {
  int id = 0;            // stable for the session's stack; never reused
  QString name;          // short and unique in the list: "small fp32", "nfor.exr"
  QString description;   // in full: the model file, architecture, precision, post-steps; or the file's path
  QString key;           // runs: the settings that made it; files: empty
  QString file;          // files: the path it was read from
  std::shared_ptr<Image> image;  // 3 channels, the render's size (copied on write while someone else holds it)
  bool complete = false;         // every pixel is the result's own (a finished run, a file)
  std::vector<Rect> rects;       // regions a run has finished, when not complete (ROI runs)
  double seconds = 0;            // how long the run took (0 for files)
  double flop = 0;               // network work of the run, when known (for time comparisons)
  RunState state = RunState::Done;
  QString stateText;             // said after the name unless Done: "running", "cancelled after 3 of 12 tiles"
  io::Provenance provenance;     // runs: what ran (method, architecture, backend, post-steps, time); files: none
  int base = 0;                  // a result at a strength: the id of the result it blends (0: none)
  float strength = 1.0f;         // ... and its strength; 1 for every other result
  bool fromFile() const { return key.isEmpty(); }
  bool atStrength() const { return base != 0; }
  bool done() const { return state == RunState::Done; }
};

}  // namespace residue::ui
