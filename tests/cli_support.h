// Support for the CLI tests: running the xgauge executable, and a fixture
// with a fresh folder per test.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace xgauge {

namespace fs = std::filesystem;
const std::string kRoot = XGAUGE_SOURCE_DIR;

struct CommandResult {
  int status;
  std::string output;  // stdout and stderr
};

inline CommandResult run(const std::string& arguments) {
  const std::string command = std::string(XGAUGE_EXECUTABLE) + " " + arguments + " 2>&1";
  FILE* pipe = ::popen(command.c_str(), "r");
  EXPECT_NE(pipe, nullptr);
  CommandResult result{0, {}};
  std::array<char, 4096> buffer{};
  while (fgets(buffer.data(), buffer.size(), pipe) != nullptr) result.output += buffer.data();
  const int status = ::pclose(pipe);
  result.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("xgauge_cli_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
            std::to_string(::getpid()));  // unique per process: two test runs at once
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string write(const std::string& name, const std::string& text) {
    const fs::path path = dir_ / name;
    std::ofstream(path) << text;
    return path.string();
  }
  std::string out(const std::string& name) const { return (dir_ / name).string(); }

  // A render command with every input valid; tests replace one piece.
  std::string renderArgs(const std::string& part, const std::string& machine,
                         const std::string& extra) const {
    return "render " + part + " --machine " + machine + " --material " + kRoot +
           "/examples/aluminium_60kev.json --rotation-deg 0 0 0 --translation-mm 0 0 400 -o " +
           out("out.tif") + " " + extra;
  }

  // Fails the test unless the run failed with `message` and wrote nothing.
  void expectCleanFailure(const CommandResult& r, const std::string& message) {
    EXPECT_NE(r.status, 0) << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << "expected '" << message << "' in:\n"
                                                         << r.output;
    EXPECT_TRUE(fs::is_empty(dir_) || !fs::exists(out("out.tif"))) << r.output;
    for (const auto& entry : fs::directory_iterator(dir_))
      EXPECT_EQ(entry.path().extension(), ".json") << "left behind: " << entry.path();
  }

  fs::path dir_;
};

}  // namespace xgauge
