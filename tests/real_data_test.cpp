// Real radiographs end to end: the HTC2022 acrylic disc (tests/data/htc2022,
// CC BY 4.0, attribution in its README) measured from two angles on the
// turntable, as a lab would, through the xgauge executable.
#include "cli_support.h"

#include <nlohmann/json.hpp>

#include <cmath>

namespace xgauge {
namespace {

// An independent four-angle fit of the same rows gave 69.575 +- 0.005 mm;
// the curve's shape, which two noisy rows cannot decide, moves the answer by
// a few hundredths (tests/data/htc2022/README.md).
constexpr double kFourAngleDiameterMm = 69.575;

nlohmann::json measureDisc(const std::string& job, const fs::path& out) {
  const CommandResult r = run("measure " + job + " -o " + out.string() + " --quiet");
  EXPECT_EQ(r.status, 0) << r.output;
  std::ifstream in(out / "result.json");
  EXPECT_TRUE(in.good()) << r.output;
  return nlohmann::json::parse(in);
}

TEST_F(Cli, TheHtc2022DiscFromTwoTurntableAnglesIsMeasuredWithAUThatCoversIt) {
  const nlohmann::json result =
      measureDisc(kRoot + "/tests/data/htc2022/job.json", fs::path(out("disc")));
  ASSERT_EQ(result["status"], "measured") << result["failures"].dump();
  const nlohmann::json& d = result["dimensions"][0];
  ASSERT_EQ(d["name"], "diameter");
  const double value = d["value_mm"], u = d["expanded_uncertainty"];
  const double error = value - kFourAngleDiameterMm;
  // Measured 69.601 mm, U 0.066 mm (k = 2).
  EXPECT_LE(std::abs(error), u) << value << " +- " << u;
  EXPECT_LT(std::abs(error), 0.04) << value;
  EXPECT_LT(u, 0.1);
  // The turned shot's pose is its reference's turned by 7.5 deg about the
  // axis 410.66 mm from the source; the disc sits within a millimetre of it.
  const nlohmann::json& a = result["radiographs"][0]["pose"]["translation_mm"];
  const nlohmann::json& b = result["radiographs"][1]["pose"]["rotation_deg"];
  EXPECT_NEAR(a[2].get<double>(), 553.74 - 410.66, 1.0);
  EXPECT_NEAR(std::abs(b[1].get<double>()), 7.5, 1e-9);
  // The budget names the turntable's own terms.
  bool turn = false, axis = false;
  for (const auto& c : result["uncertainty"]["dimensions"][0]["components"]) {
    turn |= c["name"] == "turn a188";
    axis |= c["name"].get<std::string>().starts_with("turntable axis point");
  }
  EXPECT_TRUE(turn && axis);
}

TEST_F(Cli, ATurnedRadiographOnAMachineWithoutATurntableIsRefusedNamingTheJob) {
  const std::string data = kRoot + "/tests/data/htc2022/";
  nlohmann::json machine = nlohmann::json::parse(std::ifstream(data + "machine.json"));
  machine.erase("turntable");
  write("machine.json", machine.dump());
  nlohmann::json job = nlohmann::json::parse(std::ifstream(data + "job.json"));
  job["machine"] = out("machine.json");
  for (const char* key : {"part", "material"}) job[key] = data + job[key].get<std::string>();
  for (auto& r : job["radiographs"]) r["image"] = data + r["image"].get<std::string>();
  const std::string file = write("job.json", job.dump());
  const CommandResult r = run("measure " + file + " -o " + out("refused") + " --quiet");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("/radiographs/1/pattern: radiograph a188 is turned, but the machine"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(out("refused") + "/result.json"));
}

}  // namespace
}  // namespace xgauge
