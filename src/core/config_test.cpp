#include "xgauge/core/config.h"
#include "xgauge/core/atomic_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace xgauge {
namespace {

TEST(Config, ReadsValuesAndAcceptsWhenAllKeysRead) {
  auto root = ConfigNode::parse(R"({"a": 1.5, "b": {"c": "x", "d": [1, 2]}})", "t.json");
  EXPECT_EQ(root.get<double>("a"), 1.5);
  auto b = root.at("b");
  EXPECT_EQ(b.get<std::string>("c"), "x");
  EXPECT_EQ(b.get<std::vector<int>>("d"), (std::vector<int>{1, 2}));
  EXPECT_NO_THROW(root.finish());
}

TEST(Config, UnknownKeyIsReportedWithHintAndPath) {
  auto root = ConfigNode::parse(R"({"dims": {"width": 1, "widht": 2}})", "part.json");
  root.at("dims").get<double>("width");
  try {
    root.finish();
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.where().file, "part.json");
    EXPECT_EQ(e.where().key_path, "/dims/widht");
    EXPECT_NE(std::string(e.what()).find("did you mean 'width'"), std::string::npos) << e.what();
  }
}

TEST(Config, UnknownKeyInObjectWithOnlyOptionalKeys) {
  auto root = ConfigNode::parse(R"({"rotaton": 1})", "pose.json");
  EXPECT_FALSE(root.has("rotation"));
  try {
    root.finish();
    FAIL() << "expected an error";
  } catch (const Error& e) {
    // The hint comes from the keys the reader asked for, even absent ones.
    EXPECT_NE(std::string(e.what()).find("did you mean 'rotation'"), std::string::npos) << e.what();
  }
}

TEST(Config, MissingKeyNamesKeyAndFile) {
  auto root = ConfigNode::parse(R"({"a": {}})", "m.json");
  try {
    root.at("a").at("pitch_mm");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "m.json: /a: missing key 'pitch_mm'");
  }
}

TEST(Config, SyntaxErrorGivesLineAndColumn) {
  try {
    ConfigNode::parse("{\n  \"a\": 1,\n  \"b\": ]\n}", "bad.json");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.where().line, 3);
    EXPECT_EQ(e.where().column, 8);
  }
}

TEST(Config, WrongTypeAndRange) {
  auto root = ConfigNode::parse(R"({"a": "7", "b": 5})", "t.json");
  EXPECT_THROW(root.get<double>("a"), Error);
  EXPECT_THROW(root.at("b").number(0, 4), Error);
  EXPECT_EQ(root.at("b").number(0, 5), 5.0);
}

TEST(Config, MissingFile) {
  EXPECT_THROW(ConfigNode::loadFile("/nonexistent/x.json"), Error);
}

TEST(AtomicFile, NoOutputWithoutCommit) {
  const auto dir = std::filesystem::temp_directory_path() / "xgauge_atomic_test";
  std::filesystem::create_directories(dir);
  const auto target = dir / "out.txt";
  std::filesystem::remove(target);
  {
    AtomicFile file(target);
    std::ofstream(file.tempPath()) << "partial";
  }
  EXPECT_FALSE(std::filesystem::exists(target));
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  writeFileAtomically(target, "done");
  std::ifstream in(target);
  std::string text;
  in >> text;
  EXPECT_EQ(text, "done");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace xgauge
