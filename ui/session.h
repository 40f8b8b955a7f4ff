// Session: the renders the viewer holds open (its image list, as tev's) and the one it shows. Each render keeps
// its AOV stack (noisy colour, AOVs, reference), its results with A and B, and its sequence; the one shown is
// in the members below, the others wait in the list. It loads on a worker thread and tells the widgets what
// changed. Widgets never touch files.
#pragma once

#include <QFutureWatcher>
#include <QObject>
#include <QStringList>
#include <deque>
#include <functional>
#include <map>
#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "core/aov/aov_loader.h"
#include "core/aov/other_layers.h"
#include "ui/frame_sequence.h"
#include "ui/result.h"

namespace residue::ui {

// What a pane can show. Noisy stands for the input render: its colour, or another AOV of the stack.
// Denoised is result A, Compare result B (ui/result.h).
enum class Source { Noisy, Denoised, Compare, Reference, Heatmap };
const char* to_string(Source s);

// The AOVs a user can page through with [ and ].
// The AOVs a pane can show (the reference is a source of its own), and their names in the UI.
inline constexpr AovRole kViewableAovs[] = {AovRole::Color, AovRole::Albedo, AovRole::Normal, AovRole::Depth,
                                            AovRole::Variance, AovRole::Motion};
QString display_name(AovRole role);

class Session : public QObject {
  Q_OBJECT
 public:
  explicit Session(QObject* parent = nullptr);
  ~Session() override;

  // Starts loading `inputs` (one file, a folder, or a set of single-AOV files) with `options` on a worker
  // thread; loaded() or loadFailed() follows. A reload or frame step in flight is superseded; another render
  // being opened is not: this one waits for it. The render joins the end of the list and is shown (without
  // `focus`: it joins unshown, unless nothing is shown); the others keep everything. Inputs already open show
  // that render instead.
  void open(const std::vector<std::filesystem::path>& inputs, const LoadOptions& options = {}, bool focus = true);

  // The image list. Every render opened (a file, a drop, a stream) is an entry until it is closed.
  int renderCount() const { return static_cast<int>(renders_.size()); }
  int currentRender() const { return current_; }  // -1 when none is open
  QString renderTitle(int index) const;           // as title() says it for the one shown
  QStringList renderInputs(int index) const;      // its files in full (none for a stream)
  int renderResultCount(int index) const;
  int renderId(int index) const;                  // stable while it is open (views, regions kept per render)
  // Shows another open render as it was left: its results, A and B, frame. Emits aboutToSwitch(), then loaded()
  // (switchedRender() is true while it is handled) and renderListChanged().
  void showRender(int index);
  // Closes an entry: the one shown gives way to its neighbour (or to nothing). A run for it is stopped.
  void closeRender(int index);
  bool switchedRender() const { return switching_; }
  void closeLive(const QString& name);  // the entry of a stream, when it is open (tev's "close image")
  // Loads a reference colour from another file for the current stack (worker thread).
  void openReference(const std::filesystem::path& file);
  // Loads the same inputs again (F5), keeping the reference file and mapping; the results are dropped.
  void reload();
  // Shows a stack that came from no file (an image a renderer streams, ui/tev_server.h), named `name`: its entry
  // of the list (made on its first image) gets the new pixels and loses its results, which were of the old ones.
  // Without `focus` (tev's grab_focus off) a stream that is not the one shown stays in the list, unshown.
  // Supersedes a load in flight when it is shown.
  void adoptLive(std::shared_ptr<const AovStack> stack, const QString& name, bool focus = true);
  QString liveName() const { return live_name_; }  // empty unless the stack came from adoptLive()
  bool loading() const { return loading_; }

  bool hasStack() const { return stack_ != nullptr; }
  // The current stack (never null after loaded()).
  std::shared_ptr<const AovStack> stack() const { return stack_; }
  const std::vector<std::filesystem::path>& inputs() const { return inputs_; }
  const LoadOptions& loadOptions() const { return options_; }
  QString title() const;  // file name(s) for the window title

  // Sequences (ui/frame_sequence.h): a render that is one frame of a sequence steps to the others. Each frame keeps
  // its results while the render is open (a new render empties them all); A and B follow the same settings from
  // frame to frame, and results added from numbered files follow the files' frames.
  const std::optional<FrameSequence>& sequence() const { return sequence_; }
  int64_t frame() const { return frame_; }  // the frame shown, when sequence()
  // Loads that frame of the sequence, with its reference; loaded() then frameChanged() follow. False when there is
  // no sequence or no such frame.
  bool showFrame(int64_t frame);
  // Frames t-1 and t+1 of the sequence, read beside frame t (with their references): null where the sequence has
  // no such frame or it could not be read. A temporal method reads them as neighbours; the temporal column and map
  // compare with frame t-1.
  std::shared_ptr<const AovStack> frameStack(int64_t frame) const;
  // What result `r` of this frame was on frame t-1: the run with the same settings, or the same numbered file's
  // frame t-1, when that frame has it; else null. The noisy input's is frame t-1's colour.
  std::shared_ptr<const Image> previousImage(const Result* r) const;

  // The reference colour, when known (from the stack or from another file).
  const Image* reference() const;
  const Image* image(Source s, AovRole aov) const;  // Heatmap: nullptr (owned by the heatmap panel)
  bool hasAov(AovRole role) const;
  // The layers of the shown render's files that no AOV took (core/aov/other_layers.h), listed from the files the
  // first time they are asked for on each stack shown.
  const std::vector<OtherLayer>& otherLayers() const;
  // One of them on the render's grid: read here, on the calling thread (a few channels of one file), the first
  // time, then kept while its stack is shown. Throws Error(Input) when the file cannot be read.
  std::shared_ptr<const Image> otherLayer(int index) const;

  // Results (ui/result.h) of the render shown: every denoise run and every image added from a file, in the
  // order they came (each open render has its own list; a reload empties it). A and B are the two being compared (ids, -1 for none): A is "the denoised image"
  // of the panes, the metrics and the exports; B is shown beside it, wiped or flipped against it.
  const std::vector<Result>& results() const { return results_; }
  const Result* result(int id) const;  // of the render shown
  bool holds(int id) const;            // in any open render (a run goes on into a render not shown)
  const Result* findRun(const QString& key) const;  // the run made with these settings, if kept
  int addResult(Result r);                          // assigns the id; emits resultsChanged()
  // A run's tile (GUI thread): copied into the result; shown at once when it is A (denoisedTileChanged).
  void setResultTile(int id, const Rect& rect, const Image& pixels);
  // Changes a result's bookkeeping (name, state, time, completeness, or its whole image); emits resultsChanged()
  // and, when its image is shown, denoisedChanged() / compareChanged().
  void updateResult(int id, const std::function<void(Result&)>& edit);
  void removeResult(int id);
  // Reads an image (the colour of an EXR: another denoiser's output, say) into the list on a worker thread;
  // resultsChanged() or resultFailed() follows. It must have the render's size.
  void addResultFile(const std::filesystem::path& file);
  int a() const { return a_; }
  int b() const { return b_; }
  void setA(int id);  // -1: none
  void setB(int id);

  // Result A's image; null when there is none. Tiles of a running denoise of A are written into it.
  const Image* denoised() const { return denoisedShared().get(); }
  // A snapshot for a worker thread: tiles that arrive later go to a copy, never into this one.
  std::shared_ptr<const Image> denoisedShared() const;
  std::shared_ptr<const Image> compareShared() const;  // result B; null when none
  // Denoising strength (core/denoise/strength.h) of A: 1 the result, 0 the noisy colour, between a blend made
  // at once from the result (no network run). Below 1 it is a result of its own beside the full one
  // ("oidn fp32 @ 50 %"), which becomes A: made when A is a full result, re-blended in place when A is already
  // one at a strength; at 1 that one goes and its full result is A again.
  void setStrength(float strength);
  float strength() const;               // A's: 1 unless A is a result at a strength
  QString denoisedDescription() const;  // A's description (with its strength)
  QString resultName(int id) const;     // empty for none

 signals:
  void loadStarted(QString what);
  void loaded();            // a new stack replaced the old one (denoised cleared)
  void loadFailed(QString message, int error_kind, QStringList inputs);
  void referenceChanged();
  void denoisedChanged();   // A is another result, or A's image was replaced as a whole (or none)
  void compareChanged();    // the same for B
  void denoisedTileChanged(residue::Rect rect);  // a tile of A
  void resultsChanged();    // a result was added, removed, renamed or finished
  void resultFailed(QString message);  // addResultFile() could not use the file
  void frameChanged();      // another frame of the sequence is shown (after loaded())
  void aboutToSwitch();     // another open render is about to be shown: the one shown is still current
  void renderListChanged(); // an entry was added, closed, renamed, or another is shown

 private:
  struct LoadResult;
  void startLoad(std::vector<std::filesystem::path> inputs, LoadOptions options, bool reference_only,
                 std::optional<int64_t> frame = std::nullopt, bool reload = false, bool focus = true);
  void finishLoad();
  void enterFrame(const LoadResult& r);  // a frame of the sequence replaces the shown one

  std::shared_ptr<const AovStack> stack_;
  std::vector<std::filesystem::path> inputs_;
  QString live_name_;
  LoadOptions options_;
  // The results at a strength made from result `base`: blended again from it, all of them or one rectangle (a
  // tile just written), with its state; emits what changed for A and B.
  void reblendFrom(int base, const std::optional<Rect>& rect = std::nullopt, bool pixels = true);
  int deriveAtStrength(int base, float strength);  // a new result `base` at `strength`; its id
  void removeOne(int id);
  QString uniqueName(const QString& name, int id) const;  // `name`, or "name (2)" when another result has it

  Result* find(int id);                 // in any open render: a run goes on into its render while another is shown
  std::vector<Result>* listOf(int id);  // the result list holding `id` (the shown one's or another render's)
  void clearResults();

  // An open render that is not shown: what the members below hold for the one that is.
  struct FrameMemory {
    std::vector<Result> results;
    int a = -1, b = -1;
  };
  struct Render {
    int id = 0;
    std::shared_ptr<const AovStack> stack;
    std::vector<std::filesystem::path> inputs;
    QString live_name;
    LoadOptions options;
    std::vector<Result> results;
    int a = -1, b = -1;
    std::optional<FrameSequence> sequence;
    int64_t frame = 0;
    std::map<int64_t, FrameMemory> memories;
    std::map<int64_t, std::shared_ptr<const AovStack>> nearby;
    QString follow_a, follow_b;
    int epoch = 0;
  };
  Render stash();               // moves the shown render's members out
  void unstash(Render&& r);     // ... and another's in
  void switchTo(int index);     // stash the shown one into its entry, unstash `index`
  Render& newEntry();           // an empty entry at the end of the list, with its id
  void showNewEntry();          // stash the shown one; an empty new entry is the one shown (its members to fill)
  int findRender(const std::vector<std::filesystem::path>& inputs, const QString& live_name) const;
  struct QueuedOpen {
    std::vector<std::filesystem::path> inputs;
    LoadOptions options;
    bool focus = true;
  };
  std::deque<QueuedOpen> queued_;  // renders asked for while another was being opened
  bool load_is_new_ = false;       // the load in flight opens a new render (it is never superseded)
  void startQueued();
  void dropLoadOfShown();
  std::vector<Render> renders_;  // the list; the entry at current_ is a husk whose members are in use below
  int current_ = -1;
  int next_render_id_ = 1;
  bool switching_ = false;

  std::vector<Result> results_;
  // The sequence's other frames: their results (kept while the render is open) and the stacks of t-1 and t+1.
  std::optional<FrameSequence> sequence_;
  int64_t frame_ = 0;
  std::map<int64_t, FrameMemory> memories_;
  std::map<int64_t, std::shared_ptr<const AovStack>> nearby_;
  QString follow_a_, follow_b_;  // what A and B showed on the frame before: a file of it arriving becomes A / B
  int next_id_ = 1;
  int a_ = -1, b_ = -1;
  int results_epoch_ = 0;  // a file added for an earlier render is dropped when it arrives
  bool loading_ = false;
  int generation_ = 0;
  // otherLayers() of the stack in layers_of_, and the ones read so far.
  mutable std::weak_ptr<const AovStack> layers_of_;
  mutable std::vector<OtherLayer> other_layers_;
  mutable std::map<int, std::shared_ptr<const Image>> layer_images_;
  QFutureWatcher<std::shared_ptr<LoadResult>>* watcher_ = nullptr;
};

}  // namespace residue::ui

Q_DECLARE_METATYPE(residue::Rect)
