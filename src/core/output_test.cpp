#include "xgauge/core/output.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/error.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

namespace xgauge {
namespace {

namespace fs = std::filesystem;

class Output : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("xgauge_output_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  size_t entries() const {
    return static_cast<size_t>(std::distance(fs::recursive_directory_iterator(dir_), {}));
  }
  fs::path dir_;
};

std::string read(const fs::path& path) {
  std::ifstream in(path);
  std::string text;
  std::getline(in, text);
  return text;
}

TEST_F(Output, TransactionHoldsFilesBackUntilCommit) {
  {
    OutputTransaction transaction;
    createOutputFolder(dir_ / "out" / "sub");
    writeFileAtomically(dir_ / "out" / "sub" / "a.txt", "first");
    writeFileAtomically(dir_ / "out" / "b.txt", "second");
    writeFileAtomically(dir_ / "out" / "b.txt", "third");  // replaces the held-back one
    EXPECT_FALSE(fs::exists(dir_ / "out" / "sub" / "a.txt"));
    EXPECT_FALSE(fs::exists(dir_ / "out" / "b.txt"));
    transaction.commit();
  }
  EXPECT_EQ(read(dir_ / "out" / "sub" / "a.txt"), "first");
  EXPECT_EQ(read(dir_ / "out" / "b.txt"), "third");
  EXPECT_EQ(entries(), 4u);  // out, out/sub, two files: no temporaries
}

TEST_F(Output, FailedTransactionRemovesItsFilesAndFolders) {
  fs::create_directories(dir_ / "kept");
  writeFileAtomically(dir_ / "kept" / "old.txt", "old");
  try {
    OutputTransaction transaction;
    createOutputFolder(dir_ / "new" / "deeper");
    writeFileAtomically(dir_ / "new" / "deeper" / "a.txt", "a");
    createOutputFolder(dir_ / "kept");
    writeFileAtomically(dir_ / "kept" / "old.txt", "replaced");
    throw Error("the work failed");
  } catch (const Error&) {
  }
  EXPECT_FALSE(fs::exists(dir_ / "new"));
  EXPECT_EQ(read(dir_ / "kept" / "old.txt"), "old");
  EXPECT_EQ(entries(), 2u);
  // Without a transaction, files go into place at once.
  writeFileAtomically(dir_ / "kept" / "old.txt", "now");
  EXPECT_EQ(read(dir_ / "kept" / "old.txt"), "now");
}

TEST_F(Output, PlacesAreCheckedBeforeWork) {
  std::ofstream(dir_ / "file") << "x";
  EXPECT_NO_THROW(checkOutputFolder(dir_));
  EXPECT_NO_THROW(checkOutputFolder(dir_ / "a" / "b"));
  EXPECT_FALSE(fs::exists(dir_ / "a"));  // checking creates nothing
  EXPECT_NO_THROW(checkOutputFile(dir_ / "file"));
  EXPECT_NO_THROW(checkOutputFile(dir_ / "new.tif"));
  const auto message = [](auto check, const fs::path& path) {
    try {
      check(path);
    } catch (const Error& e) {
      EXPECT_EQ(e.where().file, path.string());
      return std::string(e.what());
    }
    ADD_FAILURE() << "no error for " << path;
    return std::string();
  };
  const auto folder = [](const fs::path& p) { checkOutputFolder(p); };
  const auto file = [](const fs::path& p) { checkOutputFile(p); };
  EXPECT_NE(message(folder, dir_ / "file").find("exists and is not a folder"), std::string::npos);
  EXPECT_NE(message(folder, dir_ / "file" / "sub").find("is not a folder"), std::string::npos);
  EXPECT_NE(message(file, dir_).find("is a folder"), std::string::npos);
  EXPECT_NE(message(file, dir_ / "missing" / "x.tif").find("does not exist"), std::string::npos);
  EXPECT_NE(message(file, "/dev/null").find("not a regular file"), std::string::npos);
  // A read-only file system refuses even root.
  EXPECT_NE(message(folder, "/proc/xgauge_out").find("cannot write in the folder /proc"),
            std::string::npos);
  EXPECT_EQ(entries(), 1u);  // no probe files left
}

}  // namespace
}  // namespace xgauge
