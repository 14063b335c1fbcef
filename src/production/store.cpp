#include "xgauge/production/store.h"

#include "sql.h"
#include "xgauge/core/digest.h"
#include "xgauge/core/error.h"
#include "xgauge/report/html.h"

#include <fmt/format.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <map>
#include <random>
#include <set>

namespace xgauge {

namespace {

// The schema's history, oldest first: migration i brings a store from
// version i to i + 1. Written once for both databases; "{id}" is each one's
// auto-numbered key. Never edit a released step: add one.
const std::vector<std::string>& migrations() {
  static const std::vector<std::string> steps = {
      // 1: lots, parts, claims, measurements and what they found.
      R"sql(
CREATE TABLE lots (id {id}, name TEXT NOT NULL UNIQUE, created_at TEXT NOT NULL);
CREATE TABLE parts (id {id}, lot_id BIGINT NOT NULL REFERENCES lots(id), name TEXT NOT NULL,
  part_index BIGINT NOT NULL, acquired_at TEXT NOT NULL, UNIQUE (lot_id, name));
CREATE TABLE claims (part_id BIGINT NOT NULL REFERENCES parts(id), inputs_digest TEXT NOT NULL,
  token TEXT NOT NULL, station TEXT NOT NULL, host TEXT NOT NULL, pid BIGINT NOT NULL,
  claimed_at TEXT NOT NULL, expires_at DOUBLE PRECISION NOT NULL,
  PRIMARY KEY (part_id, inputs_digest));
CREATE TABLE measurements (id {id}, part_id BIGINT NOT NULL REFERENCES parts(id),
  inputs_digest TEXT NOT NULL, inputs_sha256 TEXT NOT NULL, software TEXT NOT NULL,
  plan TEXT NOT NULL, plan_sha256 TEXT NOT NULL, station TEXT NOT NULL,
  measured_at TEXT NOT NULL, status TEXT NOT NULL, seconds DOUBLE PRECISION NOT NULL,
  report TEXT NOT NULL, UNIQUE (part_id, inputs_digest));
CREATE TABLE dimensions (measurement_id BIGINT NOT NULL REFERENCES measurements(id),
  seq INTEGER NOT NULL, name TEXT NOT NULL, value DOUBLE PRECISION NOT NULL, unit TEXT NOT NULL,
  expanded_uncertainty DOUBLE PRECISION, identifiable INTEGER NOT NULL, verified INTEGER NOT NULL,
  nominal DOUBLE PRECISION, lower_limit DOUBLE PRECISION, upper_limit DOUBLE PRECISION,
  verdict TEXT NOT NULL, PRIMARY KEY (measurement_id, name));
CREATE TABLE warnings (measurement_id BIGINT NOT NULL REFERENCES measurements(id),
  seq INTEGER NOT NULL, text TEXT NOT NULL, PRIMARY KEY (measurement_id, seq));
CREATE TABLE residual_regions (measurement_id BIGINT NOT NULL REFERENCES measurements(id),
  seq INTEGER NOT NULL, radiograph TEXT NOT NULL, centre_u_px DOUBLE PRECISION NOT NULL,
  centre_v_px DOUBLE PRECISION NOT NULL, area_mm2 DOUBLE PRECISION NOT NULL,
  peak DOUBLE PRECISION NOT NULL, sigmas DOUBLE PRECISION NOT NULL, sign TEXT NOT NULL,
  PRIMARY KEY (measurement_id, seq));
)sql",
      // 2: which verification a result used (result.json "verification"),
      // and the alarms SPC raises.
      R"sql(
ALTER TABLE measurements ADD COLUMN verification TEXT NOT NULL DEFAULT '';
CREATE TABLE alarms (id {id}, lot_id BIGINT NOT NULL REFERENCES lots(id),
  dimension TEXT NOT NULL, rule TEXT NOT NULL, chart TEXT NOT NULL, part TEXT NOT NULL,
  position BIGINT NOT NULL, value DOUBLE PRECISION NOT NULL, detail TEXT NOT NULL,
  raised_at TEXT NOT NULL, UNIQUE (lot_id, dimension, rule, part));
)sql",
      // 3: SPC alarms per analysis: a lot's current analysis (one row per
      // lot, its time), and each alarm's analysis. Re-running the analysis
      // replaces the lot's alarms with its own; alarms stored before this
      // version have no analysis until then.
      R"sql(
CREATE TABLE spc_analyses (id {id}, lot_id BIGINT NOT NULL UNIQUE REFERENCES lots(id),
  analysed_at TEXT NOT NULL);
ALTER TABLE alarms ADD COLUMN analysis_id BIGINT REFERENCES spc_analyses(id);
)sql",
  };
  return steps;
}

std::string dialectSql(const std::string& sql, sql::Dialect dialect) {
  const std::string id =
      dialect == sql::Dialect::kSqlite ? "INTEGER PRIMARY KEY" : "BIGSERIAL PRIMARY KEY";
  std::string out = sql;
  for (size_t at; (at = out.find("{id}")) != std::string::npos;) out.replace(at, 4, id);
  return out;
}

double unixSeconds() {
  using namespace std::chrono;
  return duration<double>(system_clock::now().time_since_epoch()).count();
}

std::string randomToken() {
  std::random_device device;
  return fmt::format("{:016x}{:016x}", (uint64_t{device()} << 32) | device(),
                     (uint64_t{device()} << 32) | device());
}

bool processAlive(int64_t pid) {
  if (pid <= 0) return false;
  return ::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM;
}

std::string hostName() {
  char name[256] = {};
  if (::gethostname(name, sizeof(name) - 1) != 0) return "unknown";
  return name;
}

StoredDimension dimensionFromRow(const sql::Row& r, size_t at) {
  StoredDimension d;
  d.name = r.text(at);
  d.value = r.real(at + 1);
  d.unit = r.text(at + 2);
  d.expanded_uncertainty = r.optionalReal(at + 3);
  d.identifiable = r.integer(at + 4) != 0;
  d.verified = r.integer(at + 5) != 0;
  d.nominal = r.optionalReal(at + 6);
  d.lower_limit = r.optionalReal(at + 7);
  d.upper_limit = r.optionalReal(at + 8);
  d.verdict = r.text(at + 9);
  return d;
}

}  // namespace

bool isPostgresUrl(const std::string& location) {
  return location.starts_with("postgresql://") || location.starts_with("postgres://");
}

Claimant Claimant::thisProcess(std::string station, double lease_s) {
  Claimant c;
  c.host = hostName();
  c.station = station.empty() ? c.host : std::move(station);
  c.pid = ::getpid();
  c.lease_s = lease_s;
  return c;
}

void fillFromResult(const nlohmann::json& result, MeasurementRecord& record) {
  record.software = result.value("software", "");
  record.status = result.value("status", "measured");
  record.seconds = result.value("seconds", 0.0);
  const auto& verification = result.value("verification", nlohmann::json());
  record.verification = verification.is_string() ? verification.get<std::string>() : "";
  record.dimensions.clear();
  // A rejected fit's values are not results (docs/method.md, "The failure
  // rule"): the store keeps its status and reasons, not its values.
  if (record.status == "measured") {
    for (const auto& d : result.at("dimensions")) {
      if (!d.value("free", false)) continue;
      StoredDimension s;
      s.name = d.at("name").get<std::string>();
      s.value = d.at("value_mm").get<double>();
      s.unit = d.value("unit", "mm");
      const auto& u = d.value("expanded_uncertainty", nlohmann::json());
      if (u.is_number()) s.expanded_uncertainty = u.get<double>();
      s.identifiable = d.value("identifiable", true);
      s.verified = d.value("verified", false);
      if (d.contains("tolerance")) {
        const auto& t = d.at("tolerance");
        s.nominal = t.at("nominal").get<double>();
        s.lower_limit = *s.nominal + t.at("lower").get<double>();
        s.upper_limit = *s.nominal + t.at("upper").get<double>();
      }
      s.verdict = d.value("verdict", "");
      record.dimensions.push_back(s);
    }
  }
  record.warnings.clear();
  for (const auto& f : result.value("failures", nlohmann::json::array()))
    record.warnings.push_back("not measured: " + f.get<std::string>());
  for (const auto& w : result.value("warnings", nlohmann::json::array()))
    record.warnings.push_back(w.get<std::string>());
  record.regions.clear();
  for (const auto& r : result.value("residual_regions", nlohmann::json::array())) {
    StoredRegion s;
    s.radiograph = r.value("radiograph", "");
    s.centre_u_px = r.at("centre_px").at(0).get<double>();
    s.centre_v_px = r.at("centre_px").at(1).get<double>();
    s.area_mm2 = r.value("area_mm2", 0.0);
    s.peak = r.value("peak", 0.0);
    s.sigmas = r.value("sigmas", 0.0);
    s.sign = r.value("sign", "");
    record.regions.push_back(s);
  }
}

ResultStore::ResultStore(std::unique_ptr<sql::Connection> connection)
    : connection_(std::move(connection)) {}
ResultStore::~ResultStore() = default;

std::unique_ptr<ResultStore> ResultStore::openAtVersion(const std::string& location, int version) {
  std::unique_ptr<ResultStore> store(new ResultStore(
      isPostgresUrl(location) ? sql::openPostgres(location) : sql::openSqlite(location)));
  store->migrate(version);
  return store;
}

std::unique_ptr<ResultStore> ResultStore::open(const std::string& location) {
  return openAtVersion(location, kStoreSchemaVersion);
}

std::string ResultStore::where() const { return connection_->where(); }

int ResultStore::schemaVersion() {
  const auto rows = connection_->query("SELECT version FROM schema_version");
  return rows.empty() ? 0 : static_cast<int>(rows[0].integer(0));
}

void ResultStore::migrate(int target) {
  sql::Connection& c = *connection_;
  // Stations opening a new store at once: one migrates, the others wait for
  // its transaction and find the schema current.
  sql::Transaction t(c);
  if (c.dialect() == sql::Dialect::kPostgres) c.query("SELECT pg_advisory_xact_lock(4747474747)");
  c.script("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)");
  auto rows = c.query("SELECT version FROM schema_version");
  if (rows.empty()) c.execute("INSERT INTO schema_version (version) VALUES (0)");
  const int current = rows.empty() ? 0 : static_cast<int>(rows[0].integer(0));
  const int known = static_cast<int>(migrations().size());
  if (current > known)
    fail(
        "{}: the results store has schema version {}, newer than this xgauge's {}: use a "
        "newer xgauge",
        c.where(), current, known);
  for (int v = current; v < target; ++v) {
    c.script(dialectSql(migrations()[static_cast<size_t>(v)], c.dialect()));
    c.execute("UPDATE schema_version SET version = ?1", {int64_t{v + 1}});
  }
  t.commit();
}

int64_t ResultStore::lotId(const std::string& lot, bool create) {
  sql::Connection& c = *connection_;
  if (create)
    c.execute("INSERT INTO lots (name, created_at) VALUES (?1, ?2) ON CONFLICT (name) DO NOTHING",
              {lot, utcTimestamp()});
  const auto rows = c.query("SELECT id FROM lots WHERE name = ?1", {lot});
  if (rows.empty()) fail("{}: no lot '{}' in the results store", c.where(), lot);
  return rows[0].integer(0);
}

Claim ResultStore::claim(const MeasurementRecord& part, const Claimant& who) {
  sql::Connection& c = *connection_;
  sql::Transaction t(c);
  const int64_t lot = lotId(part.lot, true);
  c.execute(
      "INSERT INTO parts (lot_id, name, part_index, acquired_at) VALUES (?1, ?2, ?3, ?4) "
      "ON CONFLICT (lot_id, name) DO NOTHING",
      {lot, part.part, part.part_index, part.acquired_at});
  const int64_t part_id =
      c.query("SELECT id FROM parts WHERE lot_id = ?1 AND name = ?2", {lot, part.part})[0].integer(
          0);
  Claim out;
  if (!c.query("SELECT id FROM measurements WHERE part_id = ?1 AND inputs_digest = ?2",
               {part_id, part.inputs_digest})
           .empty()) {
    out.outcome = ClaimOutcome::kAlreadyMeasured;
    t.commit();
    return out;
  }
  out.token = randomToken();
  const double now = unixSeconds();
  const std::vector<sql::Value> mine = {part_id,        part.inputs_digest, out.token,
                                        who.station,    who.host,           who.pid,
                                        utcTimestamp(), now + who.lease_s};
  if (c.execute("INSERT INTO claims (part_id, inputs_digest, token, station, host, pid, "
                "claimed_at, expires_at) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8) "
                "ON CONFLICT (part_id, inputs_digest) DO NOTHING",
                mine) == 1) {
    t.commit();
    return out;
  }
  // Held: take it over only from a process that is gone or a lease run out,
  // and only if nobody else did in between (the old token still there).
  const auto held = c.query(
      "SELECT token, station, host, pid, expires_at FROM claims WHERE part_id = ?1 AND "
      "inputs_digest = ?2",
      {part_id, part.inputs_digest});
  if (!held.empty()) {
    const auto& h = held[0];
    const bool dead = h.text(2) == who.host && !processAlive(h.integer(3));
    if (dead || h.real(4) < now) {
      auto taken = mine;
      taken.push_back(h.text(0));
      if (c.execute("UPDATE claims SET token = ?3, station = ?4, host = ?5, pid = ?6, "
                    "claimed_at = ?7, expires_at = ?8 WHERE part_id = ?1 AND inputs_digest = ?2 "
                    "AND token = ?9",
                    taken) == 1) {
        t.commit();
        return out;
      }
    }
    out.holder = fmt::format("{} on {} (pid {})", h.text(1), h.text(2), h.integer(3));
  }
  out.outcome = ClaimOutcome::kClaimedElsewhere;
  out.token.clear();
  t.commit();
  return out;
}

bool ResultStore::record(const MeasurementRecord& r, const std::string& token) {
  sql::Connection& c = *connection_;
  sql::Transaction t(c);
  const int64_t lot = lotId(r.lot, true);
  c.execute(
      "INSERT INTO parts (lot_id, name, part_index, acquired_at) VALUES (?1, ?2, ?3, ?4) "
      "ON CONFLICT (lot_id, name) DO NOTHING",
      {lot, r.part, r.part_index, r.acquired_at});
  const int64_t part_id =
      c.query("SELECT id FROM parts WHERE lot_id = ?1 AND name = ?2", {lot, r.part})[0].integer(0);
  const auto inserted = c.query(
      "INSERT INTO measurements (part_id, inputs_digest, inputs_sha256, software, plan, "
      "plan_sha256, station, measured_at, status, seconds, report, verification) VALUES (?1, ?2, "
      "?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12) ON CONFLICT (part_id, inputs_digest) DO NOTHING "
      "RETURNING id",
      {part_id, r.inputs_digest, r.inputs_sha256.dump(), r.software, r.plan, r.plan_sha256,
       r.station, r.measured_at, r.status, r.seconds, r.report, r.verification});
  if (inserted.empty()) return false;  // rolled back: measured by another station first
  const int64_t id = inserted[0].integer(0);
  int64_t seq = 0;
  for (const auto& d : r.dimensions)
    c.execute(
        "INSERT INTO dimensions (measurement_id, seq, name, value, unit, expanded_uncertainty, "
        "identifiable, verified, nominal, lower_limit, upper_limit, verdict) VALUES (?1, ?2, ?3, "
        "?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)",
        {id, seq++, d.name, d.value, d.unit, sql::optional(d.expanded_uncertainty),
         int64_t{d.identifiable}, int64_t{d.verified}, sql::optional(d.nominal),
         sql::optional(d.lower_limit), sql::optional(d.upper_limit), d.verdict});
  seq = 0;
  for (const auto& w : r.warnings)
    c.execute("INSERT INTO warnings (measurement_id, seq, text) VALUES (?1, ?2, ?3)",
              {id, seq++, w});
  seq = 0;
  for (const auto& g : r.regions)
    c.execute(
        "INSERT INTO residual_regions (measurement_id, seq, radiograph, centre_u_px, "
        "centre_v_px, area_mm2, peak, sigmas, sign) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
        {id, seq++, g.radiograph, g.centre_u_px, g.centre_v_px, g.area_mm2, g.peak, g.sigmas,
         g.sign});
  c.execute("DELETE FROM claims WHERE part_id = ?1 AND inputs_digest = ?2 AND token = ?3",
            {part_id, r.inputs_digest, token});
  t.commit();
  return true;
}

void ResultStore::release(const MeasurementRecord& r, const std::string& token) {
  connection_->execute("DELETE FROM claims WHERE token = ?1 AND inputs_digest = ?2",
                       {token, r.inputs_digest});
}

std::vector<std::string> ResultStore::lots() {
  std::vector<std::string> out;
  for (const auto& row : connection_->query("SELECT name FROM lots ORDER BY id"))
    out.push_back(row.text(0));
  return out;
}

std::vector<StoredPart> ResultStore::lotSeries(const std::string& lot) {
  sql::Connection& c = *connection_;
  const int64_t lot_id = lotId(lot, false);
  // The latest measurement of each part (a part re-shot has several).
  const std::string latest =
      "FROM parts p JOIN measurements m ON m.part_id = p.id WHERE p.lot_id = ?1 AND m.id = "
      "(SELECT MAX(id) FROM measurements WHERE part_id = p.id)";
  std::vector<StoredPart> parts;
  std::map<int64_t, size_t> by_measurement;
  for (const auto& r : c.query("SELECT m.id, p.name, p.part_index, p.acquired_at, m.measured_at, "
                               "m.status, m.station " +
                                   latest + " ORDER BY p.part_index, p.acquired_at, p.name",
                               {lot_id})) {
    StoredPart p;
    p.part = r.text(1);
    p.part_index = r.integer(2);
    p.acquired_at = r.text(3);
    p.measured_at = r.text(4);
    p.status = r.text(5);
    p.station = r.text(6);
    by_measurement[r.integer(0)] = parts.size();
    parts.push_back(std::move(p));
  }
  for (const auto& r :
       c.query("SELECT d.measurement_id, d.name, d.value, d.unit, d.expanded_uncertainty, "
               "d.identifiable, d.verified, d.nominal, d.lower_limit, d.upper_limit, d.verdict " +
                   std::string("FROM dimensions d JOIN measurements m ON d.measurement_id = m.id "
                               "JOIN parts p ON m.part_id = p.id WHERE p.lot_id = ?1 ORDER BY "
                               "d.measurement_id, d.seq"),
               {lot_id})) {
    const auto at = by_measurement.find(r.integer(0));
    if (at != by_measurement.end()) parts[at->second].dimensions.push_back(dimensionFromRow(r, 1));
  }
  return parts;
}

int64_t ResultStore::measurementCount(const std::string& lot) {
  return connection_
      ->query(
          "SELECT COUNT(*) FROM measurements m JOIN parts p ON m.part_id = p.id JOIN lots l "
          "ON p.lot_id = l.id WHERE l.name = ?1",
          {lot})[0]
      .integer(0);
}

int ResultStore::recordAnalysis(const std::vector<std::string>& lots,
                                const std::vector<StoredAlarm>& alarms,
                                const std::string& analysed_at, std::vector<StoredAlarm>* fresh) {
  sql::Connection& c = *connection_;
  const auto key = [](const std::string& dimension, const std::string& rule,
                      const std::string& part) { return dimension + '\n' + rule + '\n' + part; };
  for (const auto& a : alarms)
    if (std::find(lots.begin(), lots.end(), a.lot) == lots.end())
      fail("{}: an alarm of lot '{}', which the analysis does not cover", c.where(), a.lot);
  sql::Transaction t(c);
  int added = 0;
  for (const auto& lot : lots) {
    const int64_t lot_id = lotId(lot, true);
    // The analysis row first: on PostgreSQL its row lock orders two
    // stations re-analysing one lot, so each replaces the other's alarms
    // whole rather than interleaving with them.
    const int64_t analysis = c.query(
                                  "INSERT INTO spc_analyses (lot_id, analysed_at) VALUES (?1, ?2) "
                                  "ON CONFLICT (lot_id) DO UPDATE SET analysed_at = "
                                  "excluded.analysed_at RETURNING id",
                                  {lot_id, analysed_at})[0]
                                 .integer(0);
    std::set<std::string> before;
    for (const auto& r :
         c.query("SELECT dimension, rule, part FROM alarms WHERE lot_id = ?1", {lot_id}))
      before.insert(key(r.text(0), r.text(1), r.text(2)));
    c.execute("DELETE FROM alarms WHERE lot_id = ?1", {lot_id});
    for (const auto& a : alarms) {
      if (a.lot != lot) continue;
      if (c.execute("INSERT INTO alarms (lot_id, dimension, rule, chart, part, position, value, "
                    "detail, raised_at, analysis_id) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, "
                    "?10) ON CONFLICT (lot_id, dimension, rule, part) DO NOTHING",
                    {lot_id, a.dimension, a.rule, a.chart, a.part, a.position, a.value, a.detail,
                     a.raised_at, analysis}) == 1 &&
          !before.count(key(a.dimension, a.rule, a.part))) {
        ++added;
        if (fresh) fresh->push_back(a);
      }
    }
  }
  t.commit();
  return added;
}

std::optional<std::string> ResultStore::analysedAt(const std::string& lot) {
  const auto rows = connection_->query(
      "SELECT s.analysed_at FROM spc_analyses s JOIN lots l ON s.lot_id = l.id WHERE l.name = ?1",
      {lot});
  return rows.empty() ? std::nullopt : std::optional<std::string>(rows[0].text(0));
}

std::vector<StoredAlarm> ResultStore::alarms(const std::string& lot) {
  std::vector<StoredAlarm> out;
  for (const auto& r : connection_->query(
           "SELECT a.dimension, a.rule, a.chart, a.part, a.position, a.value, a.detail, "
           "a.raised_at FROM alarms a JOIN lots l ON a.lot_id = l.id WHERE l.name = ?1 ORDER BY "
           "a.position, a.dimension, a.rule",
           {lot})) {
    StoredAlarm a;
    a.lot = lot;
    a.dimension = r.text(0);
    a.rule = r.text(1);
    a.chart = r.text(2);
    a.part = r.text(3);
    a.position = r.integer(4);
    a.value = r.real(5);
    a.detail = r.text(6);
    a.raised_at = r.text(7);
    out.push_back(a);
  }
  return out;
}

}  // namespace xgauge
