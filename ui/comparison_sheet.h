// A comparison sheet: the images of a comparison (noisy, each result, the reference) in a grid on one PNG, each
// under its name and over its scores, with a title line. Made for a report or a review: unlike a grab of the
// window it has no empty space, no widgets, and every image at the same scale (fit into a cell, or 1:1).
#pragma once

#include <QImage>
#include <QStringList>
#include <vector>

namespace residue::ui {

struct SheetPanel {
  QString label;      // "A: small fp32", "Reference"
  QImage image;       // display-encoded, full size
  QStringList lines;  // drawn under the image, e.g. "relMSE 0.00213  SSIM 0.9412  PSNR 31.2 dB"
  // A region of interest: where it lies in `image` (outlined there), its pixels, shown enlarged under the image
  // (nearest neighbour, so pixels stay pixels), and its scores under them. Empty: none.
  QRect region;
  QImage detail;
  QStringList detail_lines;
};

struct SheetOptions {
  QString title;       // the top line: the render, the reference, the display settings
  int max_edge = 512;  // each image is scaled to fit this many pixels on its long side; 0: 1:1
  int max_columns = 4;
};

// The panels in rows of at most max_columns (as square a grid as fits), on white.
QImage comparison_sheet(const std::vector<SheetPanel>& panels, const SheetOptions& options);

}  // namespace residue::ui
