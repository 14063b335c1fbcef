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

inline StoredAlarm alarm(const std::string& lot, const std::string& rule, const std::string& part,
                         int64_t position, const std::string& raised_at) {
  return {lot, "width", rule, part, "individuals", position, 21.01, "a pattern", raised_at};
}

inline std::vector<std::string> alarmKeys(ResultStore& store, const std::string& lot) {
  std::vector<std::string> out;
  for (const auto& a : store.alarms(lot)) out.push_back(a.rule + " " + a.part + " " + a.raised_at);
  return out;
}

TEST_P(StoreTest, AnAlarmIsStoredOncePerAnalysis) {
  auto store = ResultStore::open(file());
  const StoredAlarm a = alarm("L1", "nelson-2", "p0010", 10, "t1");
  EXPECT_EQ(store->recordAnalysis({"L1"}, {a, a}, "t1"), 1);
  ASSERT_EQ(store->alarms("L1").size(), 1u);
  EXPECT_EQ(store->alarms("L1")[0].part, "p0010");
  EXPECT_EQ(store->analysedAt("L1"), "t1");
}

// The case: a re-run raised 2 alarms and the store showed 6. Each
// analysis replaces the lot's alarms with its own; the count of new ones is
// against the analysis before; other lots keep theirs.
TEST_P(StoreTest, ReRunningAnAnalysisLeavesOnlyItsOwnAlarms) {
  auto store = ResultStore::open(file());
  EXPECT_FALSE(store->analysedAt("L1").has_value());
  std::vector<StoredAlarm> fresh;
  EXPECT_EQ(store->recordAnalysis({"L1", "L2"},
                                  {alarm("L1", "nelson-2", "p0010", 10, "t1"),
                                   alarm("L1", "nelson-1", "p0012", 12, "t1"),
                                   alarm("L2", "nelson-1", "p0003", 3, "t1")},
                                  "t1", &fresh),
            3);
  EXPECT_EQ(fresh.size(), 3u);
  EXPECT_EQ(alarmKeys(*store, "L1"),
            (std::vector<std::string>{"nelson-2 p0010 t1", "nelson-1 p0012 t1"}));
  // Re-run over L1 with other limits: p0010's alarm again, p0012's gone, one new.
  fresh.clear();
  EXPECT_EQ(store->recordAnalysis({"L1"},
                                  {alarm("L1", "nelson-2", "p0010", 10, "t2"),
                                   alarm("L1", "mr-1", "p0020", 20, "t2")},
                                  "t2", &fresh),
            1);
  ASSERT_EQ(fresh.size(), 1u);
  EXPECT_EQ(fresh[0].part, "p0020");
  EXPECT_EQ(alarmKeys(*store, "L1"),
            (std::vector<std::string>{"nelson-2 p0010 t2", "mr-1 p0020 t2"}));
  EXPECT_EQ(store->analysedAt("L1"), "t2");
  EXPECT_EQ(alarmKeys(*store, "L2"), (std::vector<std::string>{"nelson-1 p0003 t1"}));
  EXPECT_EQ(store->analysedAt("L2"), "t1");
  // In control at the third run: no alarm left.
  EXPECT_EQ(store->recordAnalysis({"L1"}, {}, "t3"), 0);
  EXPECT_TRUE(store->alarms("L1").empty());
  EXPECT_EQ(store->analysedAt("L1"), "t3");
  EXPECT_EQ(store->alarms("L2").size(), 1u);
  // Every stored alarm belongs to its lot's current analysis.
  EXPECT_EQ(store->connection()
                .query("SELECT COUNT(*) FROM alarms a JOIN spc_analyses s ON a.analysis_id = s.id "
                       "AND a.lot_id = s.lot_id")[0]
                .integer(0),
            1);
  // An alarm of a lot the analysis does not name is refused, changing nothing.
  EXPECT_THROW(store->recordAnalysis({"L1"}, {alarm("L2", "nelson-5", "p0004", 4, "t4")}, "t4"),
               Error);
  EXPECT_EQ(store->analysedAt("L1"), "t3");
  EXPECT_EQ(alarmKeys(*store, "L2"), (std::vector<std::string>{"nelson-1 p0003 t1"}));
}

// A version-2 store kept every analysis's alarms together: migrated, they
// stay (no analysis of theirs is known) until the lot's next analysis
// replaces them.
TEST_P(StoreTest, AVersionTwoStoresAlarmsStayUntilTheLotsNextAnalysis) {
  {
    auto old = ResultStore::openAtVersion(file(), 2);
    old->connection().script(
        "INSERT INTO lots (name, created_at) VALUES ('L1', 't');"
        "INSERT INTO alarms (lot_id, dimension, rule, chart, part, position, value, detail, "
        "raised_at) VALUES (1, 'width', 'nelson-1', 'individuals', 'p1', 1, 1.0, 'd', 'run1'), "
        "(1, 'width', 'nelson-2', 'individuals', 'p9', 9, 1.0, 'd', 'run2');");
    EXPECT_THROW(old->connection().query("SELECT COUNT(*) FROM spc_analyses"), Error);
  }
  auto store = ResultStore::open(file());
  EXPECT_EQ(store->schemaVersion(), kStoreSchemaVersion);
  EXPECT_EQ(alarmKeys(*store, "L1"),
            (std::vector<std::string>{"nelson-1 p1 run1", "nelson-2 p9 run2"}));
  EXPECT_FALSE(store->analysedAt("L1").has_value());
  EXPECT_EQ(store->recordAnalysis({"L1"}, {alarm("L1", "nelson-2", "p9", 9, "run3")}, "run3"), 0);
  EXPECT_EQ(alarmKeys(*store, "L1"), (std::vector<std::string>{"nelson-2 p9 run3"}));
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
  EXPECT_EQ(store->schemaVersion(), kStoreSchemaVersion);
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
