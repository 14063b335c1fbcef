// Test helpers for STEP parts: the solids of occt_solids.h written as STEP
// files in the test's folder, and path-length renders to compare parts
// pixel by pixel.
#pragma once

#include "test_files.h"
#include "xray/test_machines.h"

#include "occt_solids.h"

#include "xgauge/geometry/part_model.h"
#include "xgauge/xray/renderer.h"

#include <IFSelect_ReturnStatus.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_PrinterOStream.hxx>
#include <STEPControl_Writer.hxx>
#include <TopoDS_Shape.hxx>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace xgauge::testing {

// Writes `shape` as a STEP file (AP214, mm) in the test's folder.
inline std::filesystem::path writeStep(const std::string& name, const TopoDS_Shape& shape) {
  // The writer reports to OCCT's default messenger: keep the test's output clean.
  Message::DefaultMessenger()->RemovePrinters(STANDARD_TYPE(Message_PrinterOStream));
  const std::filesystem::path path = testFile(name);
  STEPControl_Writer writer;
  EXPECT_EQ(writer.Transfer(shape, STEPControl_AsIs), IFSelect_RetDone);
  EXPECT_EQ(writer.Write(path.string().c_str()), IFSelect_RetDone);
  return path;
}

// A part's dimension values by name.
inline std::map<std::string, double> valuesByName(const PartModel& part,
                                                  const std::vector<double>& values) {
  std::map<std::string, double> named;
  for (size_t i = 0; i < values.size(); ++i) named[part.dimensions()[i].name] = values[i];
  return named;
}

inline double maxAbsDifference(const ImageT<double>& a, const ImageT<double>& b) {
  double worst = 0.0;
  for (size_t i = 0; i < a.size(); ++i)
    worst = std::max(worst, std::abs(a.pixels()[i] - b.pixels()[i]));
  return worst;
}

// Path lengths (mm) through `mesh` at `pose`, n x n samples per pixel.
inline ImageT<double> renderPaths(const Machine& machine, const TriangleMesh& mesh,
                                  const Pose& pose, int n) {
  std::vector<Vec3> world;
  RenderOptions options;
  options.samples_per_axis = n;
  ImageT<double> image;
  renderPathLength(machine, posed(mesh, pose, world), options, image);
  return image;
}

// Places `centre` (part frame) at `at` after rotating by Euler angles (deg).
inline Pose poseAbout(const Vec3& angles_deg, const Vec3& centre, const Vec3& at) {
  Pose pose = Pose::fromEulerDeg(angles_deg, Vec3::Zero());
  pose.translation_mm = at - pose.rotation * centre;
  return pose;
}

}  // namespace xgauge::testing
