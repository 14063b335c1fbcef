// The scatter's weight and width from the halo around a wedge block, over a
// range of detectors, magnifications, weights and widths, with the panel's
// column darkening and noise: known answers from the lab's own effects.
#include "xgauge/calibrate/halo.h"

#include "core/expect_error.h"
#include "xgauge/core/progress.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/blur.h"
#include "xgauge/lab/detector.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/xray/renderer.h"

#include <gtest/gtest.h>

#include <spdlog/spdlog.h>

#include <random>

namespace xgauge {
namespace {

const std::string kRoot = XGAUGE_SOURCE_DIR;

struct Case {
  int side;  // detector columns = rows
  double pitch_mm;
  double magnification;  // of the block's back face
  double offset_px;      // principal point right of the centre
  double turn_deg;       // the block turned about the beam
  double weight, sigma_px, darkening;
};

// The wedge block rendered with an aluminium-like curve, scattered, darkened,
// noisy (sigma 0.003) and normalized by its open beam's level far from the
// block (the corner), as a flat field and white region would.
Image wedgeShot(const Case& s, uint64_t seed) {
  Machine machine;
  machine.source_detector_distance_mm = 1000.0;
  machine.columns = machine.rows = s.side;
  machine.pitch_u_mm = machine.pitch_v_mm = s.pitch_mm;
  machine.cx_px = 0.5 * s.side + s.offset_px, machine.cy_px = 0.5 * s.side - 3.3;
  const ExponentialSum curve({{0.55, 0.045}, {0.35, 0.13}, {0.1, 0.5}});
  const PartModel part = PartModel::load(kRoot + "/parts/wedge_block.json");
  const TriangleMesh mesh = part.mesh(part.nominalValues());
  const double z = 1000.0 * (1.0 - 1.0 / s.magnification);  // from the detector
  // The block's centre on the beam's axis, turned about it.
  Pose pose = Pose::fromEulerDeg(Vec3(0, 0, s.turn_deg), Vec3(0.0, 0.0, z));
  pose.translation_mm += pose.rotation * Vec3(0.0, -45.0, 0.0);
  std::vector<Vec3> world;
  poseVertices(pose, mesh.vertices, world);
  RenderOptions options;
  options.samples_per_axis = 2;
  Image image;
  renderIntensity(machine, {world, mesh.triangles}, TransmissionTable::forMaterial(curve, 200.0),
                  options, image);
  image = scatterBlur(std::move(image), s.weight, s.sigma_px);
  darkenColumns(image, s.darkening);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.003);
  double open = 0.0;
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) open += static_cast<double>(image(x, y)) / 64.0;
  for (float& p : image.pixels())
    p = static_cast<float>(static_cast<double>(p) / open + noise(rng));
  return image;
}

TEST(ScatterHalo, WeightAndWidthComeBackOverARangeOfSetups) {
  setProgressEnabled(false);
  const Case setups[] = {
      // side, pitch, magnification, offset, turn, weight, sigma px, darkening
      {512, 0.4, 2.0, 0.0, 0.0, 0.139, 250.0, 0.0},
      {1024, 0.2, 1.5, 40.0, 90.0, 0.06, 400.0, 0.015},
      {640, 0.3, 1.8, -50.0, 180.0, 0.19, 200.0, 0.01},
  };
  int index = 0;
  for (const Case& s : setups) {
    SCOPED_TRACE(::testing::Message() << "setup " << index);
    const Image image = wedgeShot(s, 7 + static_cast<uint64_t>(index++));
    const HaloFit fit = fitScatterHalo(image, s.pitch_mm, "shot.tif");
    EXPECT_NEAR(fit.scatter.weight, s.weight, 0.15 * s.weight);
    EXPECT_NEAR(fit.scatter.sigma_mm, s.sigma_px * s.pitch_mm, 0.25 * s.sigma_px * s.pitch_mm);
    EXPECT_NEAR(fit.column_darkening, s.darkening, 0.005);
    // Each uncertainty states at least the defaults of a typed-in scatter.
    EXPECT_GE(fit.scatter.weight_uncertainty, 0.05 * fit.scatter.weight);
    EXPECT_GE(fit.scatter.sigma_uncertainty_mm, 0.1 * fit.scatter.sigma_mm);
    // Without the scatter and the darkening the open beam is flat at 1.
    EXPECT_NEAR(fit.primary(3, 3), 1.0, 0.02);
    EXPECT_NEAR(fit.primary(s.side - 4, s.side / 2), 1.0, 0.02);
  }
}

TEST(ScatterHalo, ADetectorWithoutScatterGetsNone) {
  setProgressEnabled(false);
  const Image image = wedgeShot({512, 0.4, 2.0, 0.0, 0.0, 0.0, 250.0, 0.0}, 3);
  const HaloFit fit = fitScatterHalo(image, 0.4, "shot.tif");
  EXPECT_FALSE(fit.scatter.enabled());
  EXPECT_NEAR(fit.column_darkening, 0.0, 0.005);
}

TEST(ScatterHalo, SaysSoWhenTheRadiographCannotDecide) {
  setProgressEnabled(false);
  // An open beam: no outline to find a halo around.
  std::mt19937_64 rng(1);
  std::normal_distribution<double> noise(0.0, 0.003);
  Image open(256, 256, 1.0f);
  for (float& p : open.pixels()) p = static_cast<float>(1.0 + noise(rng));
  expectErrorMentioning([&] { fitScatterHalo(open, 0.4, "open.tif"); }, "sharp outline");
  // The block filling the detector: too little open beam around it.
  const Image filled = wedgeShot({256, 0.2, 2.0, 0.0, 0.0, 0.139, 250.0, 0.0}, 4);
  expectErrorMentioning([&] { fitScatterHalo(filled, 0.2, "filled.tif"); }, "give the job");
}

}  // namespace
}  // namespace xgauge
