#include "ui/export_all.h"

#include <QObject>
#include <QPainter>
#include <cstring>

#include "core/denoise/provenance_of.h"
#include "core/io/atomic_file.h"
#include "core/io/exr_writer.h"
#include "core/io/map_writer.h"
#include "core/io/provenance.h"
#include "core/util/error.h"
#include "ui/heatmap_panel.h"

namespace residue::ui {

QString file_stem(const QString& name) {
  // An added file is named by its file name: its extension is not part of the stem ("nfor.exr" -> "nfor").
  QString base = name;
  for (const char* ext : {".exr", ".png", ".jpg", ".jpeg", ".hdr", ".tif", ".tiff"})
    if (base.endsWith(QLatin1String(ext), Qt::CaseInsensitive) && base.size() > static_cast<int>(std::strlen(ext))) {
      base.chop(static_cast<int>(std::strlen(ext)));
      break;
    }
  QString out;
  for (const QChar c : base) {
    if (c.isLetterOrNumber() || c == '.' || c == '-' || c == '_') out += c;
    else if (!out.endsWith('_')) out += '_';
  }
  while (out.endsWith('_')) out.chop(1);
  return out.isEmpty() ? QStringLiteral("result") : out;
}

namespace {
struct Planned {
  std::filesystem::path path;
  std::function<void(const std::filesystem::path&, bool)> write;
};

std::vector<Planned> plan(const ExportAllInputs& in, const std::filesystem::path& folder) {
  std::vector<Planned> out;
  const auto at = [&](const QString& name) { return folder / name.toStdString(); };
  // The pixels written: the whole image, or the region's.
  const auto part = [&in](const Image& image) { return in.crop ? crop(image, *in.crop) : image; };
  if (in.results_exr && in.stack) {
    for (const auto& r : in.results) {
      if (!r.image) continue;
      out.push_back({at(file_stem(r.name) + ".exr"), [&in, r, part](const std::filesystem::path& p, bool overwrite) {
                       write_result_exr(p, part(*r.image), *in.stack, r, overwrite, true, "zip", in.crop);
                     }});
    }
    // A region's bundle holds what it is compared with too.
    if (in.crop) {
      Result noisy;
      noisy.name = "noisy";
      noisy.description = QString::fromStdString(in.stack->color.source.file);
      out.push_back({at("noisy.exr"), [&in, noisy, part](const std::filesystem::path& p, bool overwrite) {
                       write_result_exr(p, part(in.stack->color.image), *in.stack, noisy, overwrite, true, "zip", in.crop);
                     }});
      if (in.reference) {
        Result ref;
        ref.name = "reference";
        ref.description = in.stack->reference ? QString::fromStdString(in.stack->reference->source.file) : QString();
        out.push_back({at("reference.exr"), [&in, ref, part](const std::filesystem::path& p, bool overwrite) {
                         write_result_exr(p, part(*in.reference), *in.stack, ref, overwrite, true, "zip", in.crop);
                       }});
      }
    }
  }
  if (in.heatmaps && in.reference) {
    for (const auto& r : in.results) {
      if (!r.image) continue;
      // One map per result, made once for both files.
      auto map = std::make_shared<std::optional<Image>>();
      const auto make = [&in, r, map, part]() -> const Image& {
        // Made on the whole image, then cut: SSIM's windows near the region's edge see the pixels beyond it.
        if (!*map)
          *map = part(in.make_map ? in.make_map(*r.image, *in.reference)
                                  : metrics::error_map(*r.image, *in.reference, metrics::MapKind::RelativeSquaredError,
                                                       in.options));
        return **map;
      };
      const QString stem = "heatmap-" + file_stem(r.name);
      out.push_back({at(stem + ".png"), [&in, r, make](const std::filesystem::path& p, bool overwrite) {
                       const Image& m = make();
                       const auto range = resolve_range(m, in.scale);
                       const QImage pic = map_with_color_bar(colorize(m, in.colormap, in.scale), in.colormap, range,
                                                             in.scale.log,
                                                             QString("%1 of %2%3").arg(in.map_name, r.name,
                                                                                       in.scale.log ? " (log)" : ""));
                       write_png(p, pic, overwrite, "heatmap PNG");
                     }});
      out.push_back({at(stem + ".exr"), [make](const std::filesystem::path& p, bool overwrite) {
                       io::write_map_exr(p, make(), overwrite);
                     }});
    }
  }
  if (in.metrics && !in.whole.rows.empty()) {
    // Each row's test_file is the image scored: an added file's path, a run's EXR written beside (its name),
    // else empty (a run whose EXR is not exported was never a file).
    const auto with_files = [&in, at](io::MetricsReport report) {
      for (io::MetricsRow& row : report.rows) {
        if (!row.test_file.empty()) continue;
        for (const auto& r : in.results)
          if (r.name.toStdString() == row.name && in.results_exr && in.stack && r.image)
            row.test_file = at(file_stem(r.name) + ".exr").string();
      }
      return report;
    };
    // A region's export: its scores are the metrics.
    const auto whole = std::make_shared<io::MetricsReport>(with_files(in.crop ? in.roi : in.whole));
    const auto roi = std::make_shared<io::MetricsReport>(with_files(in.roi));
    for (const char* ext : {".json", ".csv"}) {
      out.push_back({at(QString("metrics") + ext), [whole](const std::filesystem::path& p, bool overwrite) {
                       io::write_metrics(p, *whole, overwrite);
                     }});
      if (!in.roi.rows.empty() && !in.crop)
        out.push_back({at(QString("metrics-roi") + ext), [roi](const std::filesystem::path& p, bool overwrite) {
                         io::write_metrics(p, *roi, overwrite);
                       }});
    }
  }
  if (in.comparison && in.sheet && !in.crop) {
    out.push_back({at("comparison.png"), [&in](const std::filesystem::path& p, bool overwrite) {
                     write_png(p, in.sheet(), overwrite, "comparison sheet");
                   }});
  }
  return out;
}
}  // namespace

std::vector<std::filesystem::path> planned_files(const ExportAllInputs& in, const std::filesystem::path& folder) {
  std::vector<std::filesystem::path> out;
  for (const auto& p : plan(in, folder)) out.push_back(p.path);
  return out;
}

QString export_all(const ExportAllInputs& in, const std::filesystem::path& folder, bool overwrite) {
  try {
    const auto files = plan(in, folder);
    if (files.empty()) return QObject::tr("Nothing to export: no results, no metrics.");
    if (!overwrite) {
      QStringList existing;
      for (const auto& f : files)
        if (std::filesystem::exists(f.path)) existing << QString::fromStdString(f.path.filename().string());
      if (!existing.isEmpty())
        return QObject::tr("Not replacing what is in %1: %2").arg(QString::fromStdString(folder.string()), existing.join(", "));
    }
    std::filesystem::create_directories(folder);
    for (const auto& f : files) f.write(f.path, overwrite);
    return {};
  } catch (const std::exception& e) {
    return QString::fromStdString(e.what());
  }
}

void write_png(const std::filesystem::path& path, const QImage& image, bool overwrite, const std::string& what) {
  io::write_atomically(path, overwrite, [&](const std::filesystem::path& tmp) {
    if (image.isNull() || !image.save(QString::fromStdString(tmp.string()), "PNG"))
      throw Error(ErrorKind::Output, "could not encode the " + what + " " + path.string());
  });
}

void write_result_exr(const std::filesystem::path& path, const Image& image, const AovStack& stack,
                      const Result& result, bool overwrite, bool half, const std::string& compression,
                      const std::optional<Rect>& crop) {
  io::ExrWriteOptions o;
  o.pixel_type = half ? io::PixelType::Half : io::PixelType::Float;
  o.compression = compression;
  keep_render_header(o, stack);
  if (crop) {
    o.data_window = {stack.data_window.x + crop->x, stack.data_window.y + crop->y, crop->width, crop->height};
    if (o.display_width == 0) {  // the frame was the data window: it still is, around the region
      o.display_width = stack.data_window.x + stack.data_window.width;
      o.display_height = stack.data_window.y + stack.data_window.height;
    }
  }
  io::Provenance p = result.provenance;
  if (!p.model) p.model = result.description.toStdString();  // an added file: its path
  p.source = stack.color.source.file;
  p.result = result.name.toStdString();
  p.written_by = "residue viewer";
  p.strength = result.strength;  // a result at a strength: its blend towards the noisy colour
  io::record(o.residue_attributes, p);
  o.overwrite = overwrite;
  io::write_exr(path, image, o);
}

QImage map_with_color_bar(const QImage& colored, Colormap colormap, std::pair<double, double> range, bool log,
                          const QString& title) {
  if (colored.isNull()) return {};
  const int bar_height = 64;
  QImage out(std::max(colored.width(), 360), colored.height() + bar_height, QImage::Format_RGB32);
  out.fill(Qt::white);
  QPainter p(&out);
  p.drawImage(0, 0, colored);
  QFont f = p.font();
  f.setPixelSize(12);
  p.setFont(f);
  paint_color_bar(p, QRect(0, colored.height() + 4, out.width(), bar_height - 8), colormap, range.first, range.second,
                  log, title, Qt::black);
  return out;
}

}  // namespace residue::ui
