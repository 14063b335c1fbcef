// Test helper: files written by a test live in a directory of their own per
// test (tests may run in parallel processes).
#pragma once

#include "xgauge/core/error.h"
#include "xgauge/geometry/part_model.h"

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

// A part model written to a file named `name` in the test's folder, loaded.
inline PartModel loadText(const std::string& text, const std::string& name = "part.json") {
  return PartModel::load(writeTestFile(name, text));
}

// Loading `text` fails with exactly this message, at this key path.
inline void expectLoadError(const std::string& text, const std::string& message,
                            const std::string& key_path) {
  try {
    loadText(text);
    FAIL() << "expected: " << message;
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), message);
    EXPECT_EQ(e.where().key_path, key_path);
    EXPECT_NE(e.where().file.find("part.json"), std::string::npos);
  }
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
