// Turning the session's images into display-ready panes (worker thread): which image each pane shows, how data
// AOVs are made visible (data_aov_for_display), and a cheap preview: every
// step-th pixel, so that a large render is on screen long before its full-resolution panes are drawn.
#pragma once

#include <QImage>
#include <memory>
#include <vector>

#include "core/aov/aov_stack.h"
#include "ui/canvas.h"
#include "ui/display_transform.h"
#include "ui/session.h"

namespace residue::ui {

struct PaneInputs {
  std::vector<Source> sources;
  std::shared_ptr<const AovStack> stack;
  AovRole aov = AovRole::Color;
  const Image* noisy = nullptr;                 // the AOV shown for Noisy (owned by stack)
  std::shared_ptr<const Image> layer;           // instead: a layer no AOV took (Session::otherLayer)
  QString layer_name;
  std::shared_ptr<const Image> denoised;  // result A
  std::shared_ptr<const Image> compare;   // result B
  std::shared_ptr<const Image> reference;
  QImage heat_image;
  std::shared_ptr<const Image> heat_map;
  QString heat_title;
  QString heat_placeholder;  // said while there is no map
  QString a_name, b_name;  // the results' names, for the pane labels
  std::shared_ptr<const DisplayTransform> display;
  DisplaySettings settings;
};

// One pane per source. step > 1 renders every step-th pixel (Pane::display_scale = step); the heatmap pane is
// always full size (it is already colour-mapped).
std::vector<Pane> render_panes(const PaneInputs& in, int step);

// A data AOV made visible (every step-th pixel), as values in [0, 1] shown without a view transform: normals as
// 0.5 n + 0.5; depth near-bright over its 1st-99th percentile; variance as standard deviation over its 99th
// percentile. Other roles are returned as they are.
Image data_aov_for_display(const Image& aov, AovRole role, int step = 1);

// A one-channel layer no AOV took (an alpha, a matte, a Z, an id), every step-th pixel, made visible without a
// view transform: as it is when its values lie in [0, 1], else over its 1st-99th percentile.
Image scalar_layer_for_display(const Image& layer, int step = 1);

// The preview step for an image: every step-th pixel leaves about `target` pixels on the long side.
int preview_step(int64_t width, int64_t height, int64_t target = 1024);

}  // namespace residue::ui
