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
    EXPECT_EQ(std::string(e.what()), "m.json:1: /a: missing key 'pitch_mm'");
  }
}

// A required key spelled wrong is the typo, not a missing key: the unknown
// key is named first, at its own line.
TEST(Config, AMisspelledRequiredKeyIsNamedAsUnknownBeforeMissing) {
  auto root = ConfigNode::parse("{\n  \"pixel_mm\": 0.2,\n  \"detektor\": {}\n}", "m.json");
  EXPECT_EQ(root.get<double>("pixel_mm"), 0.2);
  try {
    root.at("detector");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "m.json:3: /detektor: unknown key 'detektor'; did you mean 'detector'?");
  }
  // A key far from the missing one (or one already read) leaves "missing".
  auto other = ConfigNode::parse(R"({"lag": 1})", "n.json");
  try {
    other.at("tag");  // one edit of three letters: not taken for a typo
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "n.json:1: /: missing key 'tag'");
  }
}

// A swap of neighbours is one edit: "sotre" is "store", not "source".
TEST(Config, DidYouMeanCountsASwapAsOneEdit) {
  auto root = ConfigNode::parse(R"({"sotre": "a.sqlite"})", "plan.json");
  EXPECT_FALSE(root.has("source"));
  EXPECT_FALSE(root.has("store"));
  try {
    root.finish();
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("did you mean 'store'?"), std::string::npos) << e.what();
  }
}

// A document derived from a node keeps the node's file and lines.
TEST(Config, ADerivedDocumentKeepsTheFileAndLines) {
  auto root = ConfigNode::parse("{\n  \"job\": {\n    \"part\": \"p.json\",\n    \"pars\": 1\n  }\n}",
                                "plan.json");
  nlohmann::json changed = root.at("job").json();
  changed["part"] = "/abs/p.json";
  const ConfigNode job = root.at("job").derived(changed);
  EXPECT_EQ(job.get<std::string>("part"), "/abs/p.json");
  try {
    job.finish();
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.where().file, "plan.json");
    EXPECT_EQ(e.where().line, 4) << e.what();
    EXPECT_EQ(e.where().key_path, "/job/pars");
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

// Parses `text` and returns the error it must raise.
Error parseError(const std::string& text) {
  try {
    ConfigNode::parse(text, "hostile.json");
  } catch (const Error& e) {
    return e;
  }
  ADD_FAILURE() << "no error for " << text.substr(0, 80);
  return Error("");
}

TEST(Config, DeepNestingIsRefusedWithItsLine) {
  // 100,000 levels used to parse, then overflow the stack when a type error
  // printed the value.
  const std::string deep = "{\n\"start\": {\"width\":\n" + std::string(100000, '[') +
                           std::string(100000, ']') + "}}";
  const Error e = parseError(deep);
  EXPECT_EQ(e.where().file, "hostile.json");
  EXPECT_EQ(e.where().line, 3);
  EXPECT_NE(std::string(e.what()).find("nested more than 128 levels"), std::string::npos)
      << e.what();
  // 128 levels are fine.
  EXPECT_NO_THROW(ConfigNode::parse(std::string(128, '[') + std::string(128, ']'), "ok.json"));
}

TEST(Config, NumberOverflowNamesTheLine) {
  const Error e = parseError("{\n  \"a\": 1,\n  \"b\": 1e400\n}");
  EXPECT_EQ(e.where().line, 3);
  EXPECT_NE(std::string(e.what()).find("number overflow"), std::string::npos) << e.what();
  EXPECT_EQ(std::string(e.what()).find("json.exception"), std::string::npos) << e.what();
  // An integer too long for 64 bits is read as a double, and overflows the same way.
  EXPECT_EQ(parseError("[\n" + std::string(400, '9') + "]").where().line, 2);
}

TEST(Config, DuplicateKeyIsRefused) {
  const Error e = parseError("{\"a\": {\"seed\": 1,\n \"seed\": 2}}");
  EXPECT_EQ(e.where().line, 2);
  EXPECT_NE(std::string(e.what()).find("key 'seed' appears twice in the object at /a"),
            std::string::npos)
      << e.what();
  // The same key in two objects is fine.
  EXPECT_NO_THROW(ConfigNode::parse(R"([{"a": 1}, {"a": 2}])", "ok.json"));
}

TEST(Config, ErrorsGiveTheLineOfTheKey) {
  const auto root = ConfigNode::parse("{\n  \"a\": {\n    \"b\": [1,\n      {\"c\": \"x\"}],\n    \"d\": 2\n  }\n}", "l.json");
  const auto line = [&](auto read) {
    try {
      read();
    } catch (const Error& e) {
      return e.where().line;
    }
    return -1;
  };
  EXPECT_EQ(line([&] { root.at("a").at("d").string(); }), 5);
  EXPECT_EQ(line([&] { root.at("a").at("b")[1].at("c").number(); }), 4);
  EXPECT_EQ(line([&] { root.at("a").at("b")[0].string(); }), 3);  // a scalar: its array's line
  EXPECT_EQ(line([&] { root.at("a").at("missing"); }), 2);
  root.at("a").at("d");
  root.at("a").at("b")[1].at("c");
  EXPECT_EQ(line([&] { root.finish(); }), -1);
  const auto unread = ConfigNode::parse("{\"a\": 1,\n\"bb\": 2}", "u.json");
  unread.get<double>("a");
  EXPECT_EQ(line([&] { unread.finish(); }), 2);
}

TEST(Config, WrongTypeMessageStaysShort) {
  const std::string big = "{\"a\": [" + std::string(100, '[') + std::string(100, ']') + "], \"s\": \"" +
                          std::string(100000, 'x') + "\"}";
  const auto root = ConfigNode::parse(big, "t.json");
  for (const char* key : {"a", "s"}) {
    try {
      root.at(key).number();
      ADD_FAILURE();
    } catch (const Error& e) {
      EXPECT_LT(std::string(e.what()).size(), 120u) << e.what();
    }
  }
}

TEST(Config, DeviceIsNotReadForEver) {
  // Found by fuzzing: a part model naming /dev/zero read until memory ran out.
  try {
    ConfigNode::loadFile("/dev/zero");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.where().file, "/dev/zero");
    EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
  }
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
