// The results store on SQLite (the cases: store_cases.h), and reading a
// result.json into a record.
#include "store_cases.h"

namespace xgauge {
namespace {

using store_cases::StoreTest;
namespace fs = std::filesystem;
INSTANTIATE_TEST_SUITE_P(Sqlite, StoreTest, ::testing::Values("sqlite"));

// Stations started together open a new store at the same instant; SQLite
// answers the switch to WAL with "database is locked" without waiting for
// the busy timeout, so opening must retry it (seen as a flaky two-station
// test before it did).
TEST(SqliteStore, StationsOpeningANewStoreTogetherAllGetIt) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("xgauge_store_race_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  constexpr int kRounds = 40, kStations = 3;
  int failed = 0;
  for (int round = 0; round < kRounds; ++round) {
    const std::string file = (dir / fmt::format("r{}.sqlite", round)).string();
    int ready[2];
    ASSERT_EQ(::pipe(ready), 0);
    std::vector<pid_t> children;
    for (int s = 0; s < kStations; ++s) {
      const pid_t pid = ::fork();
      ASSERT_GE(pid, 0);
      if (pid == 0) {
        ::close(ready[1]);
        char go;
        [[maybe_unused]] const auto n = ::read(ready[0], &go, 1);  // all start at once
        try {
          ResultStore::open(file);
        } catch (...) {
          ::_exit(1);
        }
        ::_exit(0);
      }
      children.push_back(pid);
    }
    ::close(ready[0]);
    ::close(ready[1]);  // end of file releases every child together
    for (const pid_t pid : children) {
      int status = 0;
      ::waitpid(pid, &status, 0);
      if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) ++failed;
    }
  }
  fs::remove_all(dir);
  EXPECT_EQ(failed, 0) << "of " << kRounds * kStations << " openings";
}

TEST(StoreResult, FillFromResultKeepsFreeDimensionsTolerancesWarningsAndRegions) {
  const auto result = nlohmann::json::parse(R"({
    "software": "xgauge 0.1.0", "status": "measured", "seconds": 2.5,
    "verification": "master.json",
    "dimensions": [
      {"name": "width", "value_mm": 20.98, "free": true, "unit": "mm",
       "expanded_uncertainty": 0.004, "identifiable": true, "verified": true,
       "tolerance": {"nominal": 21.0, "lower": -0.05, "upper": 0.03, "source": "job"},
       "verdict": "conforms"},
      {"name": "length", "value_mm": 40.0, "free": false, "unit": "mm"},
      {"name": "depth", "value_mm": 7.1, "free": true, "unit": "mm",
       "expanded_uncertainty": null, "identifiable": false, "verified": false}],
    "warnings": ["w1"],
    "residual_regions": [{"radiograph": "t00", "centre_px": [1.5, 2.5], "area_mm2": 0.3,
                          "peak": 0.02, "sigmas": 9.0, "sign": "brighter"}]})");
  MeasurementRecord r;
  fillFromResult(result, r);
  EXPECT_EQ(r.verification, "master.json");
  ASSERT_EQ(r.dimensions.size(), 2u);
  EXPECT_EQ(r.dimensions[0].lower_limit, 20.95);
  EXPECT_DOUBLE_EQ(*r.dimensions[0].upper_limit, 21.03);
  EXPECT_TRUE(r.dimensions[0].verified);
  EXPECT_FALSE(r.dimensions[1].expanded_uncertainty.has_value());
  EXPECT_FALSE(r.dimensions[1].identifiable);
  ASSERT_EQ(r.regions.size(), 1u);
  EXPECT_EQ(r.regions[0].centre_v_px, 2.5);
  // A rejected fit keeps its reasons, not its values.
  auto rejected = result;
  rejected["status"] = "not measured";
  rejected["failures"] = {"misfit"};
  fillFromResult(rejected, r);
  EXPECT_TRUE(r.dimensions.empty());
  EXPECT_EQ(r.warnings.front(), "not measured: misfit");
}

}  // namespace
}  // namespace xgauge
