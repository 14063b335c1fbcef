// Pictures of a part for a person naming its faces and checking its
// dimensions (`xgauge part faces`, `xgauge part check`): orthographic views
// of its closed mesh, flat shaded, each triangle coloured by the region it
// belongs to (a face, or "moved by this dimension"), with the regions'
// borders drawn and a point of each region's visible part where its label
// goes.
//
// A z-buffer rasteriser written here: the pictures need nothing a GPU or a
// scene-graph library (VTK, OCCT's viewer) would add, and those need a
// display or an OpenGL context that a lab's server or CI does not have.
#pragma once

#include "xgauge/core/transform.h"
#include "xgauge/geometry/mesh.h"

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

namespace xgauge {

// Looking at the part from `towards_viewer` (part frame), with `up` upwards
// in the picture.
struct ViewDirection {
  std::string name;
  Vec3 towards_viewer;
  Vec3 up;
};
// From the top (+z), from the front (-y) and from the front right above
// (1, -1, 1): together they show every face of most parts.
std::vector<ViewDirection> standardViews();

using Rgb = std::array<uint8_t, 3>;

struct PartPicture {
  std::string view;  // ViewDirection::name
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;  // row-major from the top, 3 bytes a pixel
  // Per pixel, the region seen there (-1: background).
  std::vector<int> region;
  // For each region seen: a pixel inside its visible part, as far as
  // possible from its border (where a label reads best), and how many
  // pixels it covers.
  struct Label {
    int region = 0;
    int x = 0, y = 0;
    int pixels = 0;
  };
  std::vector<Label> labels;
};

// The square picture of `size_px` pixels framing `frame_mm` (the part's
// box, any orientation) from `view`. `region` gives each triangle's region
// (>= 0), `colour` a region's colour. Back faces are culled: the mesh must be
// one closed outward surface (no CSG).
PartPicture drawPart(std::span<const Vec3> vertices, std::span<const Triangle> triangles,
                     std::span<const int> region, const std::function<Rgb(int)>& colour,
                     const ViewDirection& view, const BoundingBox& frame_mm, int size_px);

// Paints the borders of `other`'s regions (where a pixel's region differs
// from its right or lower neighbour's, background included) onto
// `picture` in `colour`, except where `unchanged` (the same regions in
// another state, may be null) has a border too: what moved, drawn over
// this picture.
void overlayOutline(PartPicture& picture, const PartPicture& other, const PartPicture* unchanged,
                    const Rgb& colour);

// PNG bytes of the picture.
std::string encodePicture(const PartPicture& picture);

}  // namespace xgauge
