// residue: the viewer. Opens the renders named on the command line; the options below also let scripts
// (tools/dev/screenshots.sh) put the window in a given state and save a screenshot of it.
#include <QApplication>
#include <QCommandLineParser>
#include <QElapsedTimer>
#include <QFutureWatcher>
#include <QIcon>
#include <QScreen>
#include <QSettings>
#include <QTabWidget>
#include <QTemporaryDir>
#include <QRegularExpression>
#include <QTimer>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <string_view>

#include "core/util/openmp_env.h"
#include "core/util/resources.h"
#include "ui/canvas.h"
#include "ui/denoise_panel.h"
#include "ui/heatmap_panel.h"
#include "ui/main_window.h"
#include "ui/session.h"

using residue::ui::MainWindow;

namespace {

// The option values a script passes, checked before the window opens: a value outside what the option takes is
// refused naming it (exit 2), never read as a fallback (a NaN exposure is a white image, a 0 tile no tile).
struct CheckedOptions {
  QStringList errors;
  void fail(const QString& option, const QString& value, const QString& expected) {
    errors << QStringLiteral("--%1 %2: expected %3").arg(option, value.isEmpty() ? QStringLiteral("\"\"") : value, expected);
  }
  void number(const QCommandLineParser& cli, const QCommandLineOption& o, double lo, double hi, const QString& expected) {
    if (!cli.isSet(o)) return;
    bool ok = false;
    const double v = cli.value(o).toDouble(&ok);
    if (!ok || !std::isfinite(v) || v < lo || v > hi) fail(o.names().last(), cli.value(o), expected);
  }
  void one_of(const QCommandLineParser& cli, const QCommandLineOption& o, const QStringList& values) {
    if (cli.isSet(o) && !values.contains(cli.value(o))) fail(o.names().last(), cli.value(o), "one of " + values.join(", "));
  }
  void matches(const QCommandLineParser& cli, const QCommandLineOption& o, const QString& pattern, const QString& expected) {
    if (cli.isSet(o) && !QRegularExpression("^(?:" + pattern + ")$").match(cli.value(o)).hasMatch())
      fail(o.names().last(), cli.value(o), expected);
  }
};

}  // namespace

int main(int argc, char** argv) {
  residue::ensure_passive_openmp(argc, argv);
  // --help and --version need no display (a farm node, an ssh session): answer them on the offscreen platform.
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "-h" || a == "--help" || a == "--help-all" || a == "-v" || a == "--version")
      qputenv("QT_QPA_PLATFORM", "offscreen");
  }
  QApplication app(argc, argv);
  QApplication::setApplicationName("residue");
  QApplication::setOrganizationName("Residue");
  QApplication::setApplicationVersion(RESIDUE_VERSION);
  QApplication::setDesktopFileName("residue");  // the installed .desktop entry, for the taskbar icon

  QCommandLineParser cli;
  cli.setApplicationDescription("Residue viewer: denoise renders and compare any results against the reference, side by side and scored.");
  cli.addHelpOption();
  cli.addVersionOption();
  cli.addPositionalArgument("files", "A render: one EXR (multilayer/multipart), a folder, or single-AOV files.");
  const QCommandLineOption reference({"r", "reference"}, "A reference image in another file.", "file");
  const QCommandLineOption map("map", "Channel mapping ROLE=[FILE:]CHANNELS (repeatable), as residue-cli.", "flag");
  const QCommandLineOption add("add", "An image to compare with the render (another denoiser's output, ...); "
                               "repeatable.", "file");
  const QCommandLineOption layout("layout", "all (grid), single, pair (A | B) or wipe (A | B).", "layout");
  const QCommandLineOption pane("pane", "In single layout: noisy, denoised (A), compare (B), reference or heatmap.",
                                "pane");
  const QCommandLineOption ab("ab", "Once every denoise is done, show results I and J (1-based, as keys 1-9) as A "
                              "and B.", "I,J");
  const QCommandLineOption tab("tab", "The side bar's tab: results, denoise, heatmap or pixel.", "tab");
  const QCommandLineOption aov("aov", "The AOV the noisy pane shows: color, albedo, normal, depth, variance or motion.",
                               "aov");
  const QCommandLineOption layer("layer", "Another layer of the render's files (one no AOV took, named as the AOV box "
                                 "lists it, e.g. ViewLayer.Combined.A) the noisy pane shows.", "name");
  const QCommandLineOption heatmap_of("heatmap-of", "What the heatmap maps: a, b, noisy or a-vs-b.", "what");
  const QCommandLineOption heatmap_kind("heatmap-kind", "The heatmap's map: rse, abs, se, ssim, diff (signed), flip (HDR-FLIP), or temporal (the error's "
                                        "change since frame t-1 along the motion, on a sequence).", "kind");
  const QCommandLineOption every_frame("every-frame", "With --denoise, on a frame of a sequence: denoise every frame in "
                                       "turn (Denoise > Every Frame), then show the frame opened.");
  const QCommandLineOption export_all("export-all", "Once everything is done, export all into DIR (ask nothing: "
                                      "fails rather than replace files).", "dir");
  const QCommandLineOption heatmap("heatmap", "Heatmap display: pane, overlay or off.", "display");
  const QCommandLineOption model("model", "Model to select in the denoise panel; with --denoise, a comma list "
                                 "runs each in turn (tiny,small,base).", "name");
  const QCommandLineOption precision("precision", "fp32 or bf16.", "precision");
  const QCommandLineOption denoise("denoise", "Denoise once loaded.");
  const QCommandLineOption tile("tile", "Denoise tile edge (64-1024; default automatic).", "pixels");
  const QCommandLineOption exposure("exposure", "Exposure in stops.", "stops");
  const QCommandLineOption roi("roi", "Region of interest x,y,w,h.", "rect");
  const QCommandLineOption zoom("zoom", "Zoom (screen pixels per image pixel) instead of fit.", "factor");
  const QCommandLineOption size("size", "Window size WxH.", "size");
  const QCommandLineOption channel("channel", "Show one channel alone, as grey: r, g, b or luminance (rgb: all).", "channel");
  const QCommandLineOption open_also("open", "Open another render too, as its own entry of the image list (the Renders "
                                     "tab); repeatable. The render named first is shown.", "render");
  const QCommandLineOption clipping("clipping", "Show the clipping warning (View > Clipping Warning).");
  const QCommandLineOption false_colour("false-colour", "Show false colour: luminance in stops about mid grey (View > False Colour).");
  const QCommandLineOption theme("theme", "system, light or dark (View > Theme; remembered).", "theme");
  const QCommandLineOption timing("timing", "Print when the render is loaded, first shown and fully analysed.");
  const QCommandLineOption cancel_after("cancel-after", "Cancel each denoise S seconds after it starts and print how "
                                        "long it took to stop (the viewer's Cancel, measured).", "seconds");
  const QCommandLineOption screenshot("screenshot", "Save a screenshot of the window to FILE and quit.", "file");
  const QCommandLineOption when("screenshot-when",
                                "loaded (default), denoised, or progress:F (a denoise F of the way through).", "when");
  const QCommandLineOption ipc_port("ipc-port", "Listen for renderers streaming over tev's protocol on this port of "
                                    "127.0.0.1 (default 14158, tev's).", "port", "14158");
  const QCommandLineOption no_ipc("no-ipc", "Do not listen for renderers.");
  const QCommandLineOption ipc_memory("ipc-memory", "Memory the streamed images may hold, all renderers together, in "
                                      "MiB (default: a quarter of this machine's RAM).", "MiB");
  for (const auto* o : {&reference, &map, &add, &layout, &pane, &ab, &tab, &heatmap, &heatmap_of, &model, &precision,
                        &denoise, &tile, &exposure, &roi, &zoom, &size, &timing, &cancel_after, &screenshot, &when, &export_all,
                        &ipc_port, &no_ipc, &ipc_memory, &aov, &layer, &heatmap_kind, &every_frame, &theme, &channel, &open_also, &clipping, &false_colour})
    cli.addOption(*o);
  cli.process(app);

  CheckedOptions checked;
  checked.number(cli, tile, 64, 1024, "a tile edge of 64 to 1024 pixels");
  checked.matches(cli, tile, "[0-9]+", "a whole number of pixels, 64 to 1024");
  checked.number(cli, zoom, 1.0 / 64.0, 256.0, "a zoom of 1/64 to 256 screen pixels per image pixel");
  checked.number(cli, exposure, -30.0, 30.0, "a finite exposure in stops, -30 to 30");
  checked.number(cli, cancel_after, 0.0, 3600.0, "a number of seconds, 0 to 3600");
  checked.number(cli, ipc_memory, 16, 1 << 24, "a whole number of MiB, 16 or more");
  checked.matches(cli, size, "[0-9]{1,4}x[0-9]{1,4}", "WxH, each 200 to 8192 pixels");
  if (cli.isSet(size)) {
    const QStringList wh = cli.value(size).split('x');
    if (wh.size() == 2 && (wh[0].toInt() < 200 || wh[0].toInt() > 8192 || wh[1].toInt() < 200 || wh[1].toInt() > 8192))
      checked.fail("size", cli.value(size), "WxH, each 200 to 8192 pixels");
  }
  checked.matches(cli, ab, "[1-9][0-9]*(,[1-9][0-9]*)?", "I or I,J: results counted from 1");
  checked.matches(cli, when, "loaded|denoised|progress:(0?\\.[0-9]*[1-9][0-9]*|1(\\.0*)?)",
                  "loaded, denoised or progress:F with 0 < F <= 1");
  checked.one_of(cli, layout, {"all", "single", "pair", "wipe"});
  checked.one_of(cli, pane, {"noisy", "denoised", "compare", "reference", "heatmap"});
  checked.one_of(cli, heatmap, {"pane", "overlay", "off"});
  checked.one_of(cli, heatmap_of, {"a", "b", "noisy", "a-vs-b"});
  checked.one_of(cli, heatmap_kind, {"rse", "abs", "se", "ssim", "diff", "flip", "temporal"});
  if (cli.isSet(every_frame) && !cli.isSet(denoise))
    checked.errors << QStringLiteral("--every-frame needs --denoise: it says how --denoise runs");
  checked.one_of(cli, precision, {"fp32", "bf16"});
  checked.one_of(cli, tab, residue::ui::MainWindow::sideTabNames());
  checked.one_of(cli, theme, {"system", "light", "dark"});
  checked.one_of(cli, channel, {"rgb", "r", "g", "b", "luminance"});
  checked.one_of(cli, aov, {"color", "albedo", "normal", "depth", "variance", "motion"});
  if (cli.value(when).startsWith("progress:") && !cli.isSet(denoise))
    checked.errors << QStringLiteral("--screenshot-when %1 needs --denoise: no denoise would get there").arg(cli.value(when));
  if (!checked.errors.isEmpty()) {
    for (const QString& e : checked.errors) std::fprintf(stderr, "residue: %s\n", qPrintable(e));
    return 2;
  }

  // RESIDUE_SETTINGS_ISOLATED (the tests): settings in a folder of their own that goes with the process, so that
  // no run reads what another saved.
  QTemporaryDir isolated_settings;
  if (qEnvironmentVariableIsSet("RESIDUE_SETTINGS_ISOLATED"))
    QSettings::setPath(QSettings::NativeFormat, QSettings::UserScope, isolated_settings.path());
  MainWindow window;
  // A screenshot shows the defaults, whatever the viewer last saved.
  if (!cli.isSet(screenshot)) window.restoreSettings();
  if (cli.isSet(theme)) window.setTheme(*MainWindow::themeFromName(cli.value(theme)));  // checked above
  if (cli.isSet(clipping)) window.setClippingWarning(true);
  if (cli.isSet(false_colour)) window.setFalseColour(true);
  if (cli.isSet(channel)) window.setChannel(*residue::ui::display_channel_from_string(cli.value(channel).toStdString()));
  if (const auto icon = residue::find_resource("icons/hicolor/256x256/apps/residue.png"))
    QApplication::setWindowIcon(QIcon::fromTheme("residue", QIcon(QString::fromStdString(icon->string()))));
  if (cli.isSet(size)) {
    const QStringList wh = cli.value(size).split('x');
    if (wh.size() == 2) window.resize(wh[0].toInt(), wh[1].toInt());
  }
  if (cli.isSet(screenshot)) window.setInteractive(false);
  window.show();
  if (!cli.isSet(no_ipc) && !cli.isSet(screenshot)) {
    bool ok = false;
    const uint port = cli.value(ipc_port).toUInt(&ok);
    if (!ok || port == 0 || port > 65535) {
      std::fprintf(stderr, "residue: --ipc-port %s: expected a port number 1 to 65535\n", qPrintable(cli.value(ipc_port)));
      return 2;
    }
    const size_t memory = cli.isSet(ipc_memory) ? static_cast<size_t>(cli.value(ipc_memory).toDouble()) << 20 : 0;
    const QString error = window.listenForRenderers(static_cast<quint16>(port), memory);
    if (!error.isEmpty()) std::fprintf(stderr, "residue: %s\n", qPrintable(error));  // the viewer works without it
  }

  residue::LoadOptions options;
  try {
    for (const QString& f : cli.values(map)) options.mapping.add_flag(f.toStdString());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "residue: %s\n", e.what());
    return 2;
  }
  if (cli.isSet(reference)) options.reference = cli.value(reference).toStdString();
  QStringList models = cli.isSet(model) ? cli.value(model).split(',', Qt::SkipEmptyParts) : QStringList();
  for (const QString& m : models) {
    if (!window.denoisePanel()->selectModel(m)) {
      std::fprintf(stderr, "residue: no model named %s\n", qPrintable(m));
      return 2;
    }
  }
  if (!models.isEmpty()) window.denoisePanel()->selectModel(models.front());
  if (cli.isSet(precision))
    window.denoisePanel()->setPrecision(residue::nn::parse_precision(cli.value(precision).toStdString()));
  if (cli.isSet(tab)) window.showSideTab(*residue::ui::MainWindow::sideTabFromName(cli.value(tab)));  // checked above
  if (cli.isSet(heatmap_of)) {
    const QString o = cli.value(heatmap_of);
    using Of = residue::ui::HeatmapPanel::Of;
    window.heatmapPanel()->setOf(o == "b" ? Of::B : o == "noisy" ? Of::Noisy : o == "a-vs-b" ? Of::AgainstB : Of::A);
  }
  if (cli.isSet(heatmap_kind)) {
    if (cli.value(heatmap_kind) == "temporal") window.heatmapPanel()->setTemporal();
    else if (cli.value(heatmap_kind) == "flip") window.heatmapPanel()->setFlip();
    else window.heatmapPanel()->setKind(*residue::metrics::map_kind_from_string(cli.value(heatmap_kind).toStdString()));
  }
  if (cli.isSet(tile)) window.denoisePanel()->setTile(cli.value(tile).toLongLong());
  if (cli.isSet(heatmap)) {
    const QString h = cli.value(heatmap);
    window.heatmapPanel()->setDisplay(h == "overlay" ? residue::ui::HeatmapPanel::Display::Overlay
                                      : h == "off"   ? residue::ui::HeatmapPanel::Display::Off
                                                     : residue::ui::HeatmapPanel::Display::Pane);
  }
  if (cli.isSet(exposure)) window.setExposure(cli.value(exposure).toDouble());

  // Applies the view options once the first images are on screen.
  bool configured = false;
  QStringList pending_models = models.isEmpty() ? QStringList{window.denoisePanel()->selectedModel()} : models;
  // --denoise with several models: the next starts when one ends (with --every-frame, once every frame has it).
  std::optional<int64_t> opened_frame;  // --every-frame: the frame to show again at the end
  QObject::connect(window.denoisePanel(), &residue::ui::DenoisePanel::finished, &app, [&] {
    if (!cli.isSet(denoise) || pending_models.isEmpty() || window.denoisingEveryFrame()) return;
    QTimer::singleShot(0, &app, [&] {
      window.denoisePanel()->selectModel(pending_models.takeFirst());
      window.denoisePanel()->start();
    });
  });
  // Once every run is done: A and B as asked (--ab), then the export (--export-all).
  bool finished_setup = false;
  auto export_done = std::make_shared<bool>(!cli.isSet(export_all));
  const auto allDone = [&] {
    const bool every_done = !cli.isSet(every_frame) || (!window.denoisingEveryFrame() && opened_frame &&
                                                        window.session()->frame() == *opened_frame);
    const bool runs_done = !cli.isSet(denoise) || (pending_models.isEmpty() && !window.denoisePanel()->running() &&
                                                   window.session()->denoised() && every_done);
    const size_t added = static_cast<size_t>(cli.values(add).size()) + (cli.isSet(denoise) ? static_cast<size_t>(models.size()) : 0);
    return configured && runs_done && window.session()->results().size() >= added && !window.busy();
  };
  auto* finisher = new QTimer(&app);
  QObject::connect(finisher, &QTimer::timeout, &app, [&, finisher] {
    // --every-frame ends on the last frame: back to the one opened.
    if (opened_frame && !window.denoisingEveryFrame() && !window.busy() && window.session()->frame() != *opened_frame &&
        pending_models.isEmpty())
      window.goToFrame(*opened_frame);
    if (!allDone()) return;
    if (!finished_setup) {
      finished_setup = true;
      if (cli.isSet(ab)) {
        const QStringList ij = cli.value(ab).split(',');
        const auto& results = window.session()->results();
        for (const QString& k : ij)
          if (k.toInt() > static_cast<int>(results.size())) {
            std::fprintf(stderr, "residue: --ab %s: there are %zu results\n", qPrintable(cli.value(ab)), results.size());
            QApplication::exit(2);
            return;
          }
        const auto id = [&](int k) { return results[static_cast<size_t>(k - 1)].id; };
        if (ij.size() >= 1) window.session()->setA(id(ij[0].toInt()));
        if (ij.size() >= 2) window.session()->setB(id(ij[1].toInt()));
      }
      return;  // the next tick, once the new panes and scores are in
    }
    finisher->stop();
    if (cli.isSet(export_all)) {
      auto* w = new QFutureWatcher<QString>(&app);
      QObject::connect(w, &QFutureWatcherBase::finished, &app, [w, export_done] {
        *export_done = true;
        const QString error = w->result();
        if (error.isEmpty()) return void(std::fprintf(stderr, "residue: exported all\n"));
        std::fprintf(stderr, "residue: --export-all: %s\n", qPrintable(error));
        QApplication::exit(1);  // a script's export that failed does not end as a success
      });
      w->setFuture(window.exportAll(cli.value(export_all), false));
    }
  });
  finisher->start(100);
  const auto configure = [&] {
    if (configured) return;
    configured = true;
    if (cli.isSet(roi)) {
      const QStringList r = cli.value(roi).split(',');
      if (r.size() == 4) window.setRoi(residue::Rect{r[0].toLongLong(), r[1].toLongLong(), r[2].toLongLong(), r[3].toLongLong()});
    }
    const QString l = cli.value(layout);
    using residue::ui::Source;
    if (l == "single" || cli.isSet(pane)) {
      const QString p = cli.value(pane);
      window.showPane(p == "denoised"    ? Source::Denoised
                      : p == "compare"   ? Source::Compare
                      : p == "reference" ? Source::Reference
                      : p == "heatmap"   ? Source::Heatmap
                                         : Source::Noisy);
    } else if (l == "wipe") {
      window.setLayout(residue::ui::ImageCanvas::Layout::Wipe);
    } else if (l == "pair") {
      window.setLayout(residue::ui::ImageCanvas::Layout::Pair);
    }
    if (cli.isSet(zoom)) window.canvas()->setView(cli.value(zoom).toDouble(), window.canvas()->center());
    if (cli.isSet(aov)) window.setAov(*residue::aov_role_from_string(cli.value(aov).toStdString()));
    if (cli.isSet(layer) && !window.setLayer(cli.value(layer))) {
      QStringList names;
      for (const auto& other : window.session()->otherLayers()) names << QString::fromStdString(other.name);
      std::fprintf(stderr, "residue: --layer %s: the render has no such layer; its other layers: %s\n",
                   qPrintable(cli.value(layer)), names.isEmpty() ? "none" : qPrintable(names.join(", ")));
      QApplication::exit(2);
      return;
    }
    if (!cli.values(add).isEmpty()) window.addResultFiles(cli.values(add));
    if (cli.isSet(denoise)) {
      window.denoisePanel()->selectModel(pending_models.takeFirst());
      if (cli.isSet(every_frame)) {
        pending_models.clear();  // one model, on every frame
        opened_frame = window.session()->frame();
        window.denoiseEveryFrame();
      } else {
        window.denoisePanel()->start();
      }
    }
  };
  QObject::connect(&window, &MainWindow::panesRendered, &app, configure);

  QElapsedTimer clock;
  clock.start();
  if (cli.isSet(timing)) {
    const auto say = [&clock](const char* what) {
      std::fprintf(stderr, "residue: %-34s %7.3f s\n", what, static_cast<double>(clock.nsecsElapsed()) * 1e-9);
    };
    QObject::connect(window.session(), &residue::ui::Session::loaded, &app, [say] { say("loaded"); });
    auto shown = std::make_shared<bool>(false);
    QObject::connect(&window, &MainWindow::panesRendered, &app, [say, shown] {
      if (!*shown) say("first shown (panes drawn)");
      *shown = true;
    });
    auto* idle = new QTimer(&app);
    QObject::connect(idle, &QTimer::timeout, &app, [&window, say, idle, shown] {
      if (*shown && !window.busy()) {
        say("analysed (metrics, heatmap)");
        idle->stop();
        // Drawing cost per frame (synchronous repaints) at fit, 1:1 and 8x, in the current layout.
        auto* canvas = window.canvas();
        for (double z : {0.0, 1.0, 8.0}) {
          if (z == 0.0) canvas->fit();
          else canvas->setView(z, canvas->center());
          QElapsedTimer t;
          t.start();
          for (int i = 0; i < 10; ++i) canvas->repaint();
          std::fprintf(stderr, "residue: frame at %-6s %5.1f ms (%d x %d canvas, %zu panes)\n",
                       z == 0.0 ? "fit" : z == 1.0 ? "1:1" : "8x", static_cast<double>(t.nsecsElapsed()) * 1e-7,
                       canvas->width(), canvas->height(), canvas->panes().size());
        }
        canvas->fit();
      }
    });
    idle->start(10);
    // Responsiveness while a denoise runs: the longest gap between ticks of a 5 ms timer on the UI thread.
    auto* tick = new QTimer(&app);
    auto last = std::make_shared<qint64>(0);
    auto worst = std::make_shared<qint64>(0);
    auto ticks = std::make_shared<qint64>(0);
    QObject::connect(tick, &QTimer::timeout, &app, [&window, &clock, last, worst, ticks] {
      const qint64 now = clock.nsecsElapsed();
      if (window.denoisePanel()->running()) {
        if (*last > 0) *worst = std::max(*worst, now - *last);
        ++*ticks;
        *last = now;
      } else {
        *last = 0;
      }
    });
    QObject::connect(window.denoisePanel(), &residue::ui::DenoisePanel::finished, &app, [say, worst, ticks] {
      say("denoise finished");
      std::fprintf(stderr, "residue: UI thread during the denoise: %lld ticks of 5 ms, longest gap %.1f ms\n",
                   static_cast<long long>(*ticks), static_cast<double>(*worst) * 1e-6);
    });
    tick->start(5);
  }

  if (cli.isSet(cancel_after)) {
    // The time from Cancel to the end of the run, as a user pressing Escape would wait for it.
    auto cancelled_at = std::make_shared<QElapsedTimer>();
    const int delay_ms = static_cast<int>(cli.value(cancel_after).toDouble() * 1000.0);
    QObject::connect(window.denoisePanel(), &residue::ui::DenoisePanel::started, &app, [&window, cancelled_at, delay_ms] {
      QTimer::singleShot(delay_ms, &window, [&window, cancelled_at] {
        if (!window.denoisePanel()->running()) return;
        const auto p = window.denoisePanel()->controller()->progress();
        std::fprintf(stderr, "residue: cancelling at tile %lld of %lld\n", static_cast<long long>(p.done),
                     static_cast<long long>(p.total));
        cancelled_at->start();
        window.denoisePanel()->cancel();
      });
    });
    QObject::connect(window.denoisePanel(), &residue::ui::DenoisePanel::finished, &app,
                     [cancelled_at](bool, const QString& message) {
                       if (!cancelled_at->isValid()) return;
                       std::fprintf(stderr, "residue: stopped %.3f s after Cancel (%s)\n",
                                    static_cast<double>(cancelled_at->nsecsElapsed()) * 1e-9, qPrintable(message));
                       cancelled_at->invalidate();
                     });
  }

  if (cli.isSet(screenshot)) {
    // Polls the window's state and saves the picture when it matches --screenshot-when and nothing is pending.
    const QString file = cli.value(screenshot);
    const QString condition = cli.isSet(when) ? cli.value(when) : QStringLiteral("loaded");
    auto* timer = new QTimer(&app);
    QObject::connect(timer, &QTimer::timeout, &app, [&, timer, file, condition, finisher, export_done] {
      if (!window.lastError().isEmpty()) {
        std::fprintf(stderr, "residue: %s\n", qPrintable(window.lastError()));
        QApplication::exit(1);
        return;
      }
      if (!configured || !window.session()->hasStack()) return;
      bool ready = false;
      if (condition.startsWith("progress:")) {
        // Mid-denoise: the bar and half-finished tiles are the point of this picture.
        ready = window.denoisePanel()->running() && window.denoisePanel()->progressFraction() >= condition.mid(9).toDouble();
        if (!ready && !window.denoisePanel()->running() && window.session()->denoised() && !window.busy()) {
          std::fprintf(stderr, "residue: --screenshot-when %s: the denoise ended before it got there\n", qPrintable(condition));
          QApplication::exit(1);
          return;
        }
      } else {
        ready = !finisher->isActive() && *export_done && allDone();
      }
      if (!ready) return;
      timer->stop();
      const QImage shot = window.grab().toImage();
      const bool ok = shot.save(file);
      std::fprintf(stderr, "residue: %s %s\n", ok ? "wrote" : "could not write", qPrintable(file));
      QApplication::exit(ok ? 0 : 1);
    });
    timer->start(100);
  }

  QStringList files = cli.positionalArguments();
  if (!files.isEmpty()) window.openFiles(files, options);
  // The other renders join the image list unshown, one after the other (the first is shown if no render was named).
  const QStringList others = cli.values(open_also);
  for (qsizetype i = 0; i < others.size(); ++i) window.openFiles({others[i]}, {}, files.isEmpty() && i == 0);
  return QApplication::exec();
}
