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

}  // namespace xgauge::testing
