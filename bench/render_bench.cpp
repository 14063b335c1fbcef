// Render speed (issue: foundation; CSG parts). Run: build/bench/render_bench
//
// Prism jaw (36 triangles) on a 409.6 mm detector at 512^2 .. 4096^2 pixels
// with 1 and 4x4 samples per pixel, with 2 x 2 and edge refinement, and a
// finely faceted cylinder of about 100,000 triangles at 2048^2; all on 2
// threads, intensity output into a preallocated image (the optimiser's use).
//
// The render with derivatives of the jaw (14 parameters, 2 x 2 samples, the
// shadow's region as a measurement renders it) against the plain render of
// the same region in the same run.
//
// CSG parts at the jaw's magnification (3.5, part about 713 mm from the
// detector): the angle bracket (Part 5, two boxes and three holes), the
// same bracket written as one L-shaped extrusion minus the holes, and the
// stepped shaft (Part 6). Each also times the prism jaw at the same size in
// the same run and reports the ratio (`jaw_ms`, `x_jaw`).
#include "xgauge/core/memory.h"
#include "xgauge/core/parallel.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/xray/derivatives.h"
#include "xgauge/xray/renderer.h"

#include <benchmark/benchmark.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>

namespace xgauge {
namespace {

const std::string kParts = std::string(XGAUGE_SOURCE_DIR) + "/parts/";

// Same physical detector at every resolution: 4096 x 0.1 mm.
Machine detector(int size) {
  Machine m;
  m.source_detector_distance_mm = 1000.0;
  m.columns = m.rows = size;
  m.pitch_u_mm = m.pitch_v_mm = 409.6 / size;
  m.cx_px = m.cy_px = 0.5 * size;
  return m;
}

const TransmissionTable& aluminium() {
  static const TransmissionTable table = TransmissionTable::forMaterial(
      ExponentialSum({{0.55, 0.035}, {0.35, 0.075}, {0.10, 0.25}}), 120.0);
  return table;
}

// One posed mesh rendered again and again into a preallocated image.
struct PosedRender {
  PosedRender(const TriangleMesh& posed_mesh, const Pose& pose, int size, int samples,
              int edge_samples = 0)
      : mesh(posed_mesh), machine(detector(size)), image(size, size) {
    poseVertices(pose, posed_mesh.vertices, world);
    options.samples_per_axis = samples;
    options.edge_samples_per_axis = edge_samples;
  }
  void operator()() {
    renderIntensity(machine, {world, mesh.triangles, mesh.csg.get()}, aluminium(), options, image);
  }
  const TriangleMesh& mesh;
  Machine machine;
  std::vector<Vec3> world;
  RenderOptions options;
  Image image;
};

void renderLoop(benchmark::State& state, const TriangleMesh& mesh, const Pose& pose, int size,
                int samples) {
  PosedRender render(mesh, pose, size, samples);
  for (auto _ : state) {
    render();
    benchmark::DoNotOptimize(render.image.pixels().data());
  }
  state.counters["triangles"] = static_cast<double>(mesh.triangles.size());
  state.counters["Mpixel/s"] = benchmark::Counter(static_cast<double>(size) * size * 1e-6,
                                                  benchmark::Counter::kIsIterationInvariantRate);
}

void BM_PrismJaw(benchmark::State& state) {
  const PartModel jaw = PartModel::load(kParts + "prism_jaw.json");
  // About 750 px wide at 4096^2 (magnification 3.6, as the thesis's jaw);
  // turned a little so no face is parallel to the rays.
  const Pose pose = Pose::fromEulerDeg({4, 17, 2}, {-37.0, -72.0, 713.0});
  renderLoop(state, jaw.mesh(jaw.nominalValues()), pose, static_cast<int>(state.range(0)),
             static_cast<int>(state.range(1)));
}
BENCHMARK(BM_PrismJaw)
    ->ArgNames({"size", "samples"})
    ->ArgsProduct({{512, 1024, 2048, 4096}, {1, 4}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_Cylinder100k(benchmark::State& state) {
  // The shipped cylinder model with 25,000 segments: 4 x 25,000 triangles.
  nlohmann::json model;
  std::ifstream(kParts + "cylinder.json") >> model;
  model["shape"]["segments"] = 25000;
  const auto path = std::filesystem::temp_directory_path() / "xgauge_bench_cylinder.json";
  std::ofstream(path) << model.dump();
  const PartModel cylinder = PartModel::load(path);
  std::filesystem::remove(path);
  const Pose pose = Pose::fromEulerDeg({20, 10, 30}, {0.0, 0.0, 713.0});
  renderLoop(state, cylinder.mesh(cylinder.nominalValues()), pose, 2048, 1);
}
BENCHMARK(BM_Cylinder100k)->Unit(benchmark::kMillisecond)->UseRealTime();

// Median milliseconds of `renders` renders of `mesh` at `pose`.
double medianRenderMs(const TriangleMesh& mesh, const Pose& pose, int size, int samples,
                      int renders, int edge_samples = 0, PixelRect region = {}) {
  PosedRender render(mesh, pose, size, samples, edge_samples);
  render.options.region = region;
  std::vector<double> ms;
  for (int i = 0; i < renders; ++i) {
    const auto start = std::chrono::steady_clock::now();
    render();
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                     .count());
  }
  std::nth_element(ms.begin(), ms.begin() + renders / 2, ms.end());
  return ms[static_cast<size_t>(renders / 2)];
}

const Pose kJawPose = Pose::fromEulerDeg({4, 17, 2}, {-37.0, -72.0, 713.0});

// The jaw with 2 x 2 samples and its bent pixels refined with m x m
// (RenderOptions::edge_samples_per_axis), against 2 x 2 alone in the same
// run (`plain_ms`, `x_plain`). Face on, its walls along the beam as in the
// replica sessions' first shot.
void BM_PrismJawEdgeRefined(benchmark::State& state) {
  const int size = static_cast<int>(state.range(0)), m = static_cast<int>(state.range(1));
  const PartModel jaw = PartModel::load(kParts + "prism_jaw.json");
  const TriangleMesh mesh = jaw.mesh(jaw.nominalValues());
  const Pose pose = Pose::fromEulerDeg({0, 0, 0}, {-40.5, -20.0, 713.5});
  const double plain_ms = medianRenderMs(mesh, pose, size, 2, 15);
  const double refined_ms = medianRenderMs(mesh, pose, size, 2, 15, m);
  PosedRender render(mesh, pose, size, 2, m);
  for (auto _ : state) {
    render();
    benchmark::DoNotOptimize(render.image.pixels().data());
  }
  state.counters["plain_ms"] = plain_ms;
  state.counters["x_plain"] = refined_ms / plain_ms;
}
BENCHMARK(BM_PrismJawEdgeRefined)
    ->ArgNames({"size", "edge"})
    ->ArgsProduct({{1024, 2048}, {4, 8}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The render with derivatives (xray/derivatives.h) of the jaw for 14
// parameters (a measurement's 8 dimensions and 6 pose parameters: every
// vertex given its own velocity), 2 x 2 samples, against the plain render of
// the same view in the same run (`plain_ms`, `x_plain`): the cost of one
// Gauss-Newton iteration's Jacobian relative to one evaluation.
void BM_PrismJawDerivatives(benchmark::State& state) {
  const int size = static_cast<int>(state.range(0));
  constexpr int kParameters = 14;
  const PartModel jaw = PartModel::load(kParts + "prism_jaw.json");
  const TriangleMesh mesh = jaw.mesh(jaw.nominalValues());
  PosedRender render(mesh, kJawPose, size, 2);
  // The region a measurement renders: the shadow's box and a margin of 8 px.
  render();
  int x0 = size, y0 = size, x1 = 0, y1 = 0;
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x)
      if (render.image(x, y) < 1.0f)
        x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y);
  if (x0 > x1) {
    state.SkipWithError("the jaw casts no shadow at this pose");
    return;
  }
  render.options.region = {std::max(0, x0 - 8), std::max(0, y0 - 8),
                           std::min(size, x1 + 9) - std::max(0, x0 - 8),
                           std::min(size, y1 + 9) - std::max(0, y0 - 8)};
  const double plain_ms = medianRenderMs(mesh, kJawPose, size, 2, 15, 0, render.options.region);
  std::vector<Vec3> velocities;
  for (int k = 0; k < kParameters; ++k)
    for (size_t v = 0; v < render.world.size(); ++v)
      velocities.emplace_back(std::sin(1.0 + k + 0.37 * static_cast<double>(v)),
                              std::cos(2.0 * k + 0.11 * static_cast<double>(v)),
                              0.5 * std::sin(0.3 * k * static_cast<double>(v)));
  IntensityDerivatives out;
  const WorldMesh world{render.world, mesh.triangles, mesh.csg.get()};
  std::vector<double> ms;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    renderIntensityDerivatives(render.machine, world, aluminium(), render.options, velocities,
                               kParameters, out);
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                     .count());
    benchmark::DoNotOptimize(out.intensity.pixels().data());
  }
  std::nth_element(ms.begin(), ms.begin() + static_cast<ptrdiff_t>(ms.size() / 2), ms.end());
  state.counters["plain_ms"] = plain_ms;
  state.counters["x_plain"] = ms[ms.size() / 2] / plain_ms;
  state.counters["region_px"] = static_cast<double>(render.options.region.area());
}
BENCHMARK(BM_PrismJawDerivatives)
    ->ArgName("size")
    ->Arg(1024)
    ->Arg(2048)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// A CSG part against the prism jaw at the same size, in the same run.
void csgLoop(benchmark::State& state, const std::string& file, const Pose& pose) {
  const int size = static_cast<int>(state.range(0));
  const PartModel part = PartModel::load(kParts + file);
  const PartModel jaw = PartModel::load(kParts + "prism_jaw.json");
  const double jaw_ms =
      medianRenderMs(jaw.mesh(jaw.nominalValues()), kJawPose, size, 1, size >= 4096 ? 9 : 25);
  const double part_ms = medianRenderMs(part.mesh(part.nominalValues()), pose, size, 1,
                                        size >= 4096 ? 9 : 25);
  renderLoop(state, part.mesh(part.nominalValues()), pose, size, 1);
  state.counters["jaw_ms"] = jaw_ms;
  state.counters["x_jaw"] = part_ms / jaw_ms;
}

// The bracket's replica pose (datasets/bracket_a.json): turned so that every
// hole is seen obliquely; about 1400 px wide at 4096^2.
const Pose kBracketPose = Pose::fromEulerDeg({10, -35, 0}, {-12.0, -12.0, 713.0});

void BM_Bracket(benchmark::State& state) { csgLoop(state, "bracket.json", kBracketPose); }
BENCHMARK(BM_Bracket)->ArgName("size")->Arg(1024)->Arg(4096)->Unit(benchmark::kMillisecond)->UseRealTime();

// The bracket at the jaw's own rotation and distance: the base plate nearly
// face-on, about as large on the detector as the jaw.
void BM_BracketAtJawPose(benchmark::State& state) {
  csgLoop(state, "bracket.json", Pose::fromEulerDeg({4, 17, 2}, {-20.0, -12.0, 713.0}));
}
BENCHMARK(BM_BracketAtJawPose)->ArgName("size")->Arg(1024)->Arg(4096)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_BracketAsExtrusion(benchmark::State& state) {
  csgLoop(state, "../examples/bracket_extruded.json", kBracketPose);
}
BENCHMARK(BM_BracketAsExtrusion)->ArgName("size")->Arg(1024)->Arg(4096)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SteppedShaft(benchmark::State& state) {
  csgLoop(state, "stepped_shaft.json", Pose::fromEulerDeg({20, 0, 10}, {0.0, -27.0, 713.0}));
}
BENCHMARK(BM_SteppedShaft)->ArgName("size")->Arg(1024)->Arg(4096)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace xgauge

int main(int argc, char** argv) {
  // The target machine has 2 cores; measure on 2 threads wherever this runs.
  xgauge::keepLargeBlocksInHeap();  // as the command line does (core/memory.h)
  xgauge::ThreadLimit limit(2);
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
