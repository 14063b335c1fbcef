// The results store's tests, run on SQLite (store_test.cpp) and on a real
// PostgreSQL server (store_postgres_test.cpp): schema and migrations,
// claims (one station per part, a dead station's claim taken over), records
// read back exactly.
#pragma once

#include "sql.h"
#include "xgauge/core/error.h"
#include "xgauge/production/store.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>

namespace xgauge {
namespace store_cases {

namespace fs = std::filesystem;

// Parameter: "sqlite", or a PostgreSQL URL whose database is emptied
// before each test.
class StoreTest : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam() != "sqlite") {
      sql::openPostgres(GetParam())->script("DROP SCHEMA public CASCADE; CREATE SCHEMA public;");
      return;
    }
    dir_ = fs::temp_directory_path() /
           fmt::format("xgauge_store_{}_{}", ::getpid(),
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  std::string file() const {
    return GetParam() == "sqlite" ? (dir_ / "results.sqlite").string() : GetParam();
  }
  fs::path dir_;
};

inline MeasurementRecord part(const std::string& id, int64_t index, const std::string& digest) {
  MeasurementRecord r;
  r.lot = "L1";
  r.part = id;
  r.part_index = index;
  r.acquired_at = "2026-12-04T10:00:00Z";
  r.inputs_digest = digest;
  r.software = "xgauge test";
  r.plan = "plan.json";
  r.plan_sha256 = "ab";
  r.station = "s1";
  r.measured_at = "2026-12-04T10:01:00Z";
  r.status = "measured";
  StoredDimension d;
  d.name = "width";
  d.value = 20.977 + 1e-3 * static_cast<double>(index) + 1.0 / 3.0 * 1e-9;  // not round in decimal
  d.unit = "mm";
  d.expanded_uncertainty = 0.0042;
  d.nominal = 21.0;
  d.lower_limit = 20.95;
  d.upper_limit = 21.05;
  d.verdict = "conforms";
  r.dimensions.push_back(d);
  StoredDimension e = d;
  e.name = "thickness";
  e.expanded_uncertainty.reset();
  e.identifiable = false;
  e.nominal.reset(), e.lower_limit.reset(), e.upper_limit.reset();
  e.verdict.clear();
  r.dimensions.push_back(e);
  r.warnings = {"a warning", "another"};
  r.regions.push_back({"t00", 10.5, 20.25, 1.5, 0.01, 7.0, "brighter"});
  return r;
}

inline Claimant station(const std::string& name, int64_t pid, std::string host = "") {
  Claimant c = Claimant::thisProcess(name, 900.0);
  c.pid = pid;
  if (!host.empty()) c.host = std::move(host);
  return c;
}

// The pid of a process that has ended.
inline int64_t deadPid() {
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ::waitpid(child, nullptr, 0);
  return child;
}

TEST_P(StoreTest, FreshStoreHasTheCurrentSchema) {
  auto store = ResultStore::open(file());
  EXPECT_EQ(store->schemaVersion(), kStoreSchemaVersion);
  EXPECT_TRUE(store->lots().empty());
  // Opening again migrates nothing and keeps the version.
  store.reset();
  EXPECT_EQ(ResultStore::open(file())->schemaVersion(), kStoreSchemaVersion);
}

TEST_P(StoreTest, OnePartIsClaimedByOneStationAndRecordedOnce) {
  auto store = ResultStore::open(file());
  const MeasurementRecord p = part("p0001", 0, "d1");
  const Claim first = store->claim(p, station("s1", ::getpid()));
  ASSERT_EQ(first.outcome, ClaimOutcome::kClaimed);
  // A second live station (the test's parent process) is refused.
  const Claim second = store->claim(p, station("s2", ::getppid()));
  EXPECT_EQ(second.outcome, ClaimOutcome::kClaimedElsewhere);
  EXPECT_NE(second.holder.find("s1"), std::string::npos) << second.holder;
  ASSERT_TRUE(store->record(p, first.token));
  EXPECT_EQ(store->claim(p, station("s2", ::getppid())).outcome, ClaimOutcome::kAlreadyMeasured);
  // Recording the same part and inputs again adds nothing.
  EXPECT_FALSE(store->record(p, first.token));
  EXPECT_EQ(store->measurementCount("L1"), 1);
  // The same part with other inputs (re-shot) is a new measurement.
  EXPECT_EQ(store->claim(part("p0001", 0, "d2"), station("s1", ::getpid())).outcome,
            ClaimOutcome::kClaimed);
}

TEST_P(StoreTest, ADeadStationsClaimIsTakenOver) {
  auto store = ResultStore::open(file());
  const MeasurementRecord p = part("p0001", 0, "d1");
  ASSERT_EQ(store->claim(p, station("s1", deadPid())).outcome, ClaimOutcome::kClaimed);
  const Claim taken = store->claim(p, station("s2", ::getpid()));
  ASSERT_EQ(taken.outcome, ClaimOutcome::kClaimed);
  EXPECT_TRUE(store->record(p, taken.token));
}

TEST_P(StoreTest, AnExpiredLeaseOfAnotherHostIsTakenOverALiveOneIsNot) {
  auto store = ResultStore::open(file());
  const MeasurementRecord p = part("p0001", 0, "d1");
  Claimant far = station("far", 1, "another-host");
  ASSERT_EQ(store->claim(p, far).outcome, ClaimOutcome::kClaimed);
  // pid 1 on another host: not ours to check, so the lease decides.
  EXPECT_EQ(store->claim(p, station("s2", ::getpid())).outcome, ClaimOutcome::kClaimedElsewhere);
  const MeasurementRecord q = part("p0002", 1, "d2");
  far.lease_s = -1.0;  // already run out
  ASSERT_EQ(store->claim(q, far).outcome, ClaimOutcome::kClaimed);
  EXPECT_EQ(store->claim(q, station("s2", ::getpid())).outcome, ClaimOutcome::kClaimed);
}

TEST_P(StoreTest, ASeriesReadsBackEveryFieldExactlyInProductionOrder) {
  auto store = ResultStore::open(file());
  for (int64_t i : {2, 0, 1}) {
    const MeasurementRecord p = part(fmt::format("p{:04d}", i), i, fmt::format("d{}", i));
    const Claim c = store->claim(p, station("s1", ::getpid()));
    ASSERT_TRUE(store->record(p, c.token));
  }
  const auto series = store->lotSeries("L1");
  ASSERT_EQ(series.size(), 3u);
  for (int64_t i = 0; i < 3; ++i) {
    const MeasurementRecord expected = part(fmt::format("p{:04d}", i), i, "");
    const StoredPart& got = series[static_cast<size_t>(i)];
    EXPECT_EQ(got.part, expected.part);
    EXPECT_EQ(got.part_index, i);
    ASSERT_EQ(got.dimensions.size(), 2u);
    for (size_t k = 0; k < 2; ++k) {
      const auto& a = got.dimensions[k];
      const auto& b = expected.dimensions[k];
      EXPECT_EQ(a.name, b.name);
      EXPECT_EQ(a.value, b.value);  // bit for bit
      EXPECT_EQ(a.expanded_uncertainty, b.expanded_uncertainty);
      EXPECT_EQ(a.identifiable, b.identifiable);
      EXPECT_EQ(a.lower_limit, b.lower_limit);
      EXPECT_EQ(a.upper_limit, b.upper_limit);
      EXPECT_EQ(a.verdict, b.verdict);
    }
  }
  EXPECT_THROW(store->lotSeries("no such lot"), Error);
}

TEST_P(StoreTest, AlarmsAreStoredOnce) {
  auto store = ResultStore::open(file());
  StoredAlarm a{"L1", "width", "nelson-2", "p0010", "individuals", 10, 21.01, "9 above", "t"};
  EXPECT_EQ(store->addAlarms({a, a}), 1);
  EXPECT_EQ(store->addAlarms({a}), 0);
  ASSERT_EQ(store->alarms("L1").size(), 1u);
  EXPECT_EQ(store->alarms("L1")[0].part, "p0010");
}

TEST_P(StoreTest, AVersionOneStoreIsMigratedWithItsData) {
  {
    auto old = ResultStore::openAtVersion(file(), 1);
    EXPECT_EQ(old->schemaVersion(), 1);
    // What a version-1 xgauge wrote: no verification column, no alarms.
    old->connection().script(
        "INSERT INTO lots (name, created_at) VALUES ('old', 't');"
        "INSERT INTO parts (lot_id, name, part_index, acquired_at) VALUES (1, 'p1', 0, 't');"
        "INSERT INTO measurements (part_id, inputs_digest, inputs_sha256, software, plan, "
        "plan_sha256, station, measured_at, status, seconds, report) VALUES (1, 'd', '{}', 'x', "
        "'p', 'h', 's', 't', 'measured', 1.0, '');"
        "INSERT INTO dimensions (measurement_id, seq, name, value, unit, identifiable, verified, "
        "verdict) VALUES (1, 0, 'width', 20.5, 'mm', 1, 0, '');");
    EXPECT_THROW(old->connection().query("SELECT COUNT(*) FROM alarms"), Error);
  }
  auto store = ResultStore::open(file());
  EXPECT_EQ(store->schemaVersion(), 2);
  const auto series = store->lotSeries("old");
  ASSERT_EQ(series.size(), 1u);
  EXPECT_EQ(series[0].dimensions.at(0).value, 20.5);
  EXPECT_EQ(store->connection().query("SELECT verification FROM measurements")[0].text(0), "");
  EXPECT_EQ(store->alarms("old").size(), 0u);
}

TEST_P(StoreTest, ANewerSchemaIsRefusedNamingTheStore) {
  ResultStore::open(file())->connection().script("UPDATE schema_version SET version = 99");
  try {
    ResultStore::open(file());
    FAIL() << "a newer schema was opened";
  } catch (const Error& e) {
    const std::string named = GetParam() == "sqlite" ? file() : "127.0.0.1";
    EXPECT_NE(std::string(e.what()).find(named), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("99"), std::string::npos) << e.what();
  }
}

}  // namespace store_cases
}  // namespace xgauge
