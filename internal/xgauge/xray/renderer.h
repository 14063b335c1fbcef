// The X-ray renderer: for every detector pixel, the path length x through the
// part along the ray from the source to the pixel (or to each of n x n
// sub-pixel samples), and the intensity I(x) of a transmission curve.
//
// Contract:
// - The mesh is closed and outward-oriented (geometry/mesh.h checks this),
//   given in world coordinates (mm), every vertex with 0 <= z < D; or, for a
//   CSG part, each of its pieces is.
// - Exactly watertight: on every sample ray the number of surface entries
//   equals the number of exits, whatever the pose (see src/xray/rasterizer.h).
// - Area sampling: n x n samples per pixel on a regular grid, sample (i, j)
//   of pixel (u, v) at continuous pixel coordinate
//   (u + (i + 0.5) / n, v + (j + 0.5) / n); the pixel value is the mean of the
//   per-sample values (intensity is averaged after I(x), not before).
// - Output images cover `region` (pixels of the detector); out(0, 0) is the
//   region's top-left pixel. Rendering a region gives exactly the values of
//   the same pixels in a full render.
// - Multithreaded with oneTBB; bit-identical results at any thread count.
#pragma once

#include "xgauge/core/transform.h"
#include "xgauge/geometry/csg.h"
#include "xgauge/image/image.h"
#include "xgauge/material/transmission_table.h"
#include "xgauge/xray/machine.h"

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace xgauge {

struct RenderOptions {
  // n: n x n samples per pixel, 1 to 16.
  int samples_per_axis = 1;
  // Detector pixels to render; an empty rectangle means the whole detector.
  PixelRect region;
  // Edge refinement, m: 0 (off) or more than n, up to 32. A pixel where the
  // n x n mean path length bends (its second difference along a row or a
  // column exceeds `edge_threshold` mm: an edge or a silhouette, where the
  // path steps or kinks), and its four neighbours, are sampled again with
  // m x m samples. n x n point samples see a step in path length only where
  // it passes a sample, so an edge-on wall moves the image in steps of 1/n
  // pixel; m x m makes the steps m/n times finer where they occur, at the
  // cost of the pixels refined. Values are as deterministic as without it,
  // and a region gives the same pixels as a full render (the bend test looks
  // 2 pixels past the region). The render with derivatives refines the same
  // pixels (xray/derivatives.h). CSG parts are not refined (their n x n
  // image is kept), nor is renderDiagnostics.
  int edge_samples_per_axis = 0;
  // mm of path length.
  double edge_threshold = 0.01;
};

// A posed mesh: vertices in world coordinates (mm), triangles outward CCW.
// With `csg`, the triangles are the CSG's pieces, each closed, and a ray's
// path is through their boolean combination (geometry/csg.h).
struct WorldMesh {
  std::span<const Vec3> vertices_mm;
  std::span<const std::array<uint32_t, 3>> triangles;
  const Csg* csg = nullptr;
};

// world[i] = pose.apply(part[i]); `world` is resized, its capacity reused.
void poseVertices(const Pose& pose, std::span<const Vec3> part_vertices,
                  std::vector<Vec3>& world_vertices);

// Why `machine` cannot render a mesh with these world vertices: the first
// vertex that is not between the detector plane (z >= 0) and the source
// (z < D), or nullopt when every vertex is. The render functions throw Error
// for such a mesh; a fit asks first and treats the pose as infeasible.
std::optional<std::string> outsideBeam(const Machine& machine,
                                       std::span<const Vec3> world_vertices_mm);

// Why these world vertices (all inside the beam, see outsideBeam) cast no
// shadow on the detector: the message gives the shadow's pixel extent;
// nullopt when the shadow's bounding box overlaps the detector.
std::optional<std::string> shadowMissesDetector(const Machine& machine,
                                                std::span<const Vec3> world_vertices_mm);

// Mean path length (mm) through the part over each pixel's samples.
void renderPathLength(const Machine& machine, const WorldMesh& mesh,
                      const RenderOptions& options, ImageT<double>& out);
void renderPathLength(const Machine& machine, const WorldMesh& mesh,
                      const RenderOptions& options, Image& out);

// Mean intensity I(x) over each pixel's samples; 1 where nothing attenuates.
void renderIntensity(const Machine& machine, const WorldMesh& mesh,
                     const TransmissionTable& transmission, const RenderOptions& options,
                     Image& out);

// Mean intensity over each pixel's samples, as renderIntensity, in double
// precision (a gradient check differences such images).
void renderIntensity(const Machine& machine, const WorldMesh& mesh,
                     const TransmissionTable& transmission, const RenderOptions& options,
                     ImageT<double>& out);

// Per-pixel evidence of watertightness, for tests and for checking a mesh.
struct RenderDiagnostics {
  ImageT<int32_t> entries;        // surface entries summed over the pixel's samples
  ImageT<int32_t> exits;          // surface exits summed over the pixel's samples
  ImageT<int32_t> unbalanced;     // samples whose entries differ from their exits
  ImageT<double> min_path_mm;     // raw (unclamped) path length, min over samples
  ImageT<double> max_path_mm;     // ... and max over samples
};
RenderDiagnostics renderDiagnostics(const Machine& machine, const WorldMesh& mesh,
                                    const RenderOptions& options);

}  // namespace xgauge
