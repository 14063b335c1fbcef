// The results store on SQLite (the cases: store_cases.h), and reading a
// result.json into a record.
#include "store_cases.h"

namespace xgauge {
namespace {

using store_cases::StoreTest;
INSTANTIATE_TEST_SUITE_P(Sqlite, StoreTest, ::testing::Values("sqlite"));

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
