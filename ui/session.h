// Session: the one document the viewer shows. It owns the loaded AOV stack (noisy colour, AOVs, reference) and
// the denoised colour, loads on a worker thread, and tells the widgets what changed. Widgets never touch files.
#pragma once

#include <QFutureWatcher>
#include <QObject>
#include <QStringList>
#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "core/aov/aov_loader.h"

namespace residue::ui {

// What a pane can show. Noisy stands for the input render: its colour, or another AOV of the stack.
enum class Source { Noisy, Denoised, Reference, Heatmap };
const char* to_string(Source s);

// The AOVs a user can page through with [ and ].
// The AOVs a pane can show (the reference is a source of its own), and their names in the UI.
inline constexpr AovRole kViewableAovs[] = {AovRole::Color, AovRole::Albedo, AovRole::Normal, AovRole::Depth,
                                            AovRole::Variance};
QString display_name(AovRole role);

class Session : public QObject {
  Q_OBJECT
 public:
  explicit Session(QObject* parent = nullptr);
  ~Session() override;

  // Starts loading `inputs` (one file, a folder, or a set of single-AOV files) with `options` on a worker
  // thread; loaded() or loadFailed() follows. A load in flight is superseded.
  void open(const std::vector<std::filesystem::path>& inputs, const LoadOptions& options = {});
  // Loads a reference colour from another file for the current stack (worker thread).
  void openReference(const std::filesystem::path& file);
  // Loads the same inputs again (F5), keeping the reference file and mapping; the denoised image is dropped.
  void reload();
  // Shows a stack that came from no file (an image a renderer streams, ui/tev_server.h), named `name`.
  // Supersedes a load in flight; the denoised result is cleared as for a new file.
  void adoptLive(std::shared_ptr<const AovStack> stack, const QString& name);
  QString liveName() const { return live_name_; }  // empty unless the stack came from adoptLive()
  bool loading() const { return loading_; }

  bool hasStack() const { return stack_ != nullptr; }
  // The current stack (never null after loaded()).
  std::shared_ptr<const AovStack> stack() const { return stack_; }
  const std::vector<std::filesystem::path>& inputs() const { return inputs_; }
  const LoadOptions& loadOptions() const { return options_; }
  QString title() const;  // file name(s) for the window title

  // The reference colour, when known (from the stack or from another file).
  const Image* reference() const;
  // The denoised colour as shown, at the current strength; empty until a denoise ran. Tiles of a running
  // denoise are written into it.
  const Image* denoised() const { return denoisedShared().get(); }
  // A snapshot for a worker thread: tiles that arrive later go to a copy, never into this one.
  std::shared_ptr<const Image> denoisedShared() const { return strength_ < 1.0f && blended_ ? blended_ : denoised_; }
  // Denoising strength (core/denoise/strength.h): 1 shows the result, 0 the noisy colour, between a blend,
  // re-made from the kept result at once (no network run). Emits denoisedChanged().
  void setStrength(float strength);
  float strength() const { return strength_; }
  const Image* image(Source s, AovRole aov) const;  // Heatmap: nullptr (owned by the heatmap panel)
  bool hasAov(AovRole role) const;

  // Starts a fresh denoised image: a copy of the noisy colour, so tiles that have not run yet show the input;
  // setDenoisedTile() then overwrites it tile by tile.
  void beginDenoised();
  void setDenoisedTile(const Rect& rect, const Image& pixels);  // GUI thread
  // Shows `image` as the denoised colour without copying it; it is copied on the first tile written into it
  // while someone else (a cache) holds it too.
  void adoptDenoised(std::shared_ptr<Image> image, QString description);
  std::shared_ptr<Image> denoisedForCache() const { return denoised_; }  // at strength 1
  QString denoisedDescription() const;  // with the strength when below 1
  void clearDenoised();

 signals:
  void loadStarted(QString what);
  void loaded();            // a new stack replaced the old one (denoised cleared)
  void loadFailed(QString message, int error_kind, QStringList inputs);
  void referenceChanged();
  void denoisedChanged();   // a whole new denoised image (or none)
  void denoisedTileChanged(residue::Rect rect);

 private:
  struct LoadResult;
  void startLoad(std::vector<std::filesystem::path> inputs, LoadOptions options, bool reference_only);
  void finishLoad();

  std::shared_ptr<const AovStack> stack_;
  std::vector<std::filesystem::path> inputs_;
  QString live_name_;
  LoadOptions options_;
  void reblend(const std::optional<Rect>& rect = std::nullopt);

  std::shared_ptr<Image> denoised_;  // the result at strength 1 (shared with the denoise panel's cache)
  std::shared_ptr<Image> blended_;   // denoised_ at strength_, when below 1
  float strength_ = 1.0f;
  QString denoised_description_;
  bool loading_ = false;
  int generation_ = 0;
  QFutureWatcher<std::shared_ptr<LoadResult>>* watcher_ = nullptr;
};

}  // namespace residue::ui

Q_DECLARE_METATYPE(residue::Rect)
