// Test helper: files written by a test live in a directory of their own per
// test (tests may run in parallel processes).
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace xgauge::testing {

inline std::filesystem::path testFile(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const auto dir = std::filesystem::temp_directory_path() / "xgauge_geometry_test" /
                   (std::string(info->test_suite_name()) + "." + info->name());
  std::filesystem::create_directories(dir);
  return dir / name;
}

inline std::filesystem::path writeTestFile(const std::string& name, const std::string& contents) {
  auto path = testFile(name);
  std::ofstream(path, std::ios::binary) << contents;
  return path;
}

// An ASCII STL of the unit corner tetrahedron (0, 0, 0), (1, 0, 0), (0, 1, 0),
// (0, 0, 1), outward.
inline const std::string kTetrahedronStl = R"(solid t
facet normal 0 0 0 outer loop vertex 0 0 0 vertex 0 1 0 vertex 1 0 0 endloop endfacet
facet normal 0 0 0 outer loop vertex 0 0 0 vertex 1 0 0 vertex 0 0 1 endloop endfacet
facet normal 0 0 0 outer loop vertex 0 0 0 vertex 0 0 1 vertex 0 1 0 endloop endfacet
facet normal 0 0 0 outer loop vertex 1 0 0 vertex 0 1 0 vertex 0 0 1 endloop endfacet
endsolid t
)";

}  // namespace xgauge::testing
