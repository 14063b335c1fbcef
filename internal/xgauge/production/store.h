// The results store: every measured part of every lot, kept in a database so
// that SPC, exports and several stations share them. SQLite by default (one
// file, no server); PostgreSQL (a postgresql:// URL) for several stations
// writing to one database. One schema for both, versioned, brought up to
// date by migrations when a store is opened (docs/formats.md, "Results
// store").
//
// Each part is measured once: a station claims a part (by lot, part id and
// its inputs' digest) in the database before measuring it and records the
// measurement and releases the claim in one transaction. A measurement is
// unique per (part, inputs' digest), so a restart after kill -9, or a
// second station, finds the part measured or claimed and leaves it. A claim
// whose owner died (same host, process gone) or whose lease ran out is taken
// over.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

namespace sql {
class Connection;
}

// The schema version this build writes; older stores are migrated on open,
// newer ones refused.
inline constexpr int kStoreSchemaVersion = 3;

struct StoredDimension {
  std::string name;
  double value = 0.0;
  std::string unit;
  std::optional<double> expanded_uncertainty;  // U, k = 2
  bool identifiable = true;
  bool verified = false;
  // The tolerance as limits (nominal + lower, nominal + upper), when given.
  std::optional<double> nominal, lower_limit, upper_limit;
  std::string verdict;  // "conforms", ..., or "" without one
};

struct StoredRegion {
  std::string radiograph;
  double centre_u_px = 0.0, centre_v_px = 0.0;
  double area_mm2 = 0.0, peak = 0.0, sigmas = 0.0;
  std::string sign;
};

// One measurement of one part, as the store keeps it.
struct MeasurementRecord {
  std::string lot, part;
  int64_t part_index = -1;  // production order; -1 unknown
  std::string acquired_at;  // the manifest's time
  std::string inputs_digest;
  nlohmann::json inputs_sha256 = nlohmann::json::object();  // file -> SHA-256
  std::string software, plan, plan_sha256, station, measured_at;
  std::string status;        // "measured" or "not measured"
  std::string verification;  // the verification file the result used, or ""
  std::string report;        // the part's output folder, or ""
  double seconds = 0.0;
  std::vector<StoredDimension> dimensions;  // free dimensions only
  std::vector<std::string> warnings;
  std::vector<StoredRegion> regions;
};

// The fields of a result.json (report/measurement.h) the store keeps.
void fillFromResult(const nlohmann::json& result, MeasurementRecord& record);

// Who claims: a station name, the host and the process.
struct Claimant {
  std::string station, host;
  int64_t pid = 0;
  double lease_s = 900.0;  // another host may take the claim over after this
  static Claimant thisProcess(std::string station, double lease_s);
};

enum class ClaimOutcome { kClaimed, kAlreadyMeasured, kClaimedElsewhere };

struct Claim {
  ClaimOutcome outcome = ClaimOutcome::kClaimed;
  std::string token;   // kClaimed: proves the claim is still ours at record()
  std::string holder;  // kClaimedElsewhere: "station on host (pid n)"
};

// An alarm SPC raised: a rule a dimension's series broke at a part.
struct StoredAlarm {
  std::string lot, dimension, rule, part, chart;
  int64_t position = 0;  // 1-based place of the part in the lot's series
  double value = 0.0;
  std::string detail, raised_at;
};

// A lot's series as SPC and the exports read it: one row per part, latest
// measurement, production order (index, then acquisition time, then id).
struct StoredPart {
  std::string part, acquired_at, measured_at, status, station;
  int64_t part_index = -1;
  std::vector<StoredDimension> dimensions;
};

class ResultStore {
 public:
  // "postgresql://..." or "postgres://...": PostgreSQL; anything else is an
  // SQLite file (created when missing). Migrates the schema to
  // kStoreSchemaVersion; refuses a newer one, naming the store.
  static std::unique_ptr<ResultStore> open(const std::string& location);
  // Opens without migrating past `version` (tests of the migrations).
  static std::unique_ptr<ResultStore> openAtVersion(const std::string& location, int version);
  ~ResultStore();
  ResultStore(const ResultStore&) = delete;
  ResultStore& operator=(const ResultStore&) = delete;

  int schemaVersion();
  std::string where() const;

  Claim claim(const MeasurementRecord& part, const Claimant& who);
  // Records the measurement and releases the claim in one transaction.
  // Returns false (and records nothing) when the part's measurement is
  // already there: another station took the claim over and finished first.
  bool record(const MeasurementRecord& record, const std::string& token);
  // Gives a claim up (the measurement failed with an input error).
  void release(const MeasurementRecord& part, const std::string& token);

  std::vector<std::string> lots();
  std::vector<StoredPart> lotSeries(const std::string& lot);
  // How many measurements the store holds for the lot (all, not latest).
  int64_t measurementCount(const std::string& lot);
  // Records an SPC analysis of `lots` at `analysed_at`: each lot's alarms
  // become those of `alarms` that are the lot's (none: the lot is in
  // control), replacing the earlier analysis's, in one transaction. Returns
  // how many were not among the lot's alarms before (same dimension, rule
  // and part), and appends them to `fresh` when given. Error for an alarm of
  // a lot not in `lots`.
  int recordAnalysis(const std::vector<std::string>& lots, const std::vector<StoredAlarm>& alarms,
                     const std::string& analysed_at, std::vector<StoredAlarm>* fresh = nullptr);
  // The lot's alarms: its current analysis's (before a store's first
  // analysis since version 3, those an earlier xgauge kept).
  std::vector<StoredAlarm> alarms(const std::string& lot);
  // When the lot's current analysis ran; nullopt before the first.
  std::optional<std::string> analysedAt(const std::string& lot);

  sql::Connection& connection() { return *connection_; }

 private:
  explicit ResultStore(std::unique_ptr<sql::Connection> connection);
  void migrate(int target);
  int64_t lotId(const std::string& lot, bool create);
  std::unique_ptr<sql::Connection> connection_;
};

bool isPostgresUrl(const std::string& location);

}  // namespace xgauge
