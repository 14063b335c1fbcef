// The SQLite connection: SQLite's C API, wrapped thinly in RAII here rather
// than through a C++ wrapper library, because the store uses a handful of
// calls (open, prepare, bind, step, finalize), the C API is the one SQLite
// documents and keeps stable, and Debian 12 packages no C++ wrapper worth a
// dependency. Handles are owned by unique_ptrs with the API's own closers,
// so an exception never leaks a statement or leaves the file open.
#include "sql.h"

#include "xgauge/core/error.h"

#include <sqlite3.h>

#include <charconv>
#include <chrono>
#include <thread>

namespace xgauge::sql {

namespace {

struct CloseDb {
  void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
};
struct Finalize {
  void operator()(sqlite3_stmt* s) const { sqlite3_finalize(s); }
};
using DbHandle = std::unique_ptr<sqlite3, CloseDb>;
using StatementHandle = std::unique_ptr<sqlite3_stmt, Finalize>;

// Another process holding the write lock is waited for this long: a
// measurement's write takes milliseconds, so only a stuck process gets here.
constexpr int kBusyTimeoutMs = 60000;
constexpr int kRetryMs = 20;

class SqliteConnection final : public Connection {
 public:
  explicit SqliteConnection(const std::string& file) : file_(file) {
    sqlite3* raw = nullptr;
    const int rc =
        sqlite3_open_v2(file.c_str(), &raw,
                        SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
    db_.reset(raw);
    if (rc != SQLITE_OK)
      fail("{}: cannot open the results store: {}", file,
           raw ? sqlite3_errmsg(raw) : sqlite3_errstr(rc));
    sqlite3_busy_timeout(db_.get(), kBusyTimeoutMs);
    // WAL: readers (spc, export) never block the stations writing, and a
    // commit survives kill -9 of the writer (it is in the log on disk).
    // Switching to WAL needs the file to itself for a moment, and SQLite
    // answers SQLITE_BUSY there without calling the busy handler when a
    // second station opens the store at the same instant; so it is retried
    // here for as long as the busy timeout would have waited.
    for (int waited_ms = 0;; waited_ms += kRetryMs) {
      const int wal = sqlite3_exec(db_.get(), "PRAGMA journal_mode=WAL", nullptr, nullptr, nullptr);
      if (wal == SQLITE_OK) break;
      if ((wal & 0xff) != SQLITE_BUSY || waited_ms >= kBusyTimeoutMs)
        fail("{}: cannot switch the results store to WAL: {}", file, sqlite3_errmsg(db_.get()));
      std::this_thread::sleep_for(std::chrono::milliseconds(kRetryMs));
    }
    script("PRAGMA foreign_keys=ON; PRAGMA synchronous=NORMAL;");
  }

  Dialect dialect() const override { return Dialect::kSqlite; }
  std::string where() const override { return file_; }

  void script(const std::string& sql) override {
    char* message = nullptr;
    if (sqlite3_exec(db_.get(), sql.c_str(), nullptr, nullptr, &message) != SQLITE_OK) {
      const std::string text = message ? message : sqlite3_errmsg(db_.get());
      sqlite3_free(message);
      fail("{}: {}", file_, text);
    }
  }

  std::vector<Row> query(const std::string& sql, const std::vector<Value>& params) override {
    StatementHandle stmt = prepare(sql, params);
    std::vector<Row> rows;
    for (;;) {
      const int rc = sqlite3_step(stmt.get());
      if (rc == SQLITE_DONE) break;
      if (rc != SQLITE_ROW) fail("{}: {} (in: {})", file_, sqlite3_errmsg(db_.get()), sql);
      const int n = sqlite3_column_count(stmt.get());
      std::vector<Value> values;
      values.reserve(static_cast<size_t>(n));
      for (int i = 0; i < n; ++i) values.push_back(column(stmt.get(), i));
      rows.emplace_back(std::move(values));
    }
    return rows;
  }

  int64_t execute(const std::string& sql, const std::vector<Value>& params) override {
    StatementHandle stmt = prepare(sql, params);
    int rc;
    while ((rc = sqlite3_step(stmt.get())) == SQLITE_ROW) {
    }
    if (rc != SQLITE_DONE) fail("{}: {} (in: {})", file_, sqlite3_errmsg(db_.get()), sql);
    return sqlite3_changes64(db_.get());
  }

  void begin() override { script("BEGIN IMMEDIATE"); }
  void commit() override { script("COMMIT"); }
  void rollback() override { script("ROLLBACK"); }

 private:
  StatementHandle prepare(const std::string& sql, const std::vector<Value>& params) {
    sqlite3_stmt* raw = nullptr;
    if (sqlite3_prepare_v2(db_.get(), sql.c_str(), static_cast<int>(sql.size()), &raw, nullptr) !=
        SQLITE_OK)
      fail("{}: {} (in: {})", file_, sqlite3_errmsg(db_.get()), sql);
    StatementHandle stmt(raw);
    for (size_t i = 0; i < params.size(); ++i) {
      const int at = static_cast<int>(i + 1);
      int rc = SQLITE_OK;
      if (const auto* v = std::get_if<int64_t>(&params[i]))
        rc = sqlite3_bind_int64(raw, at, *v);
      else if (const auto* d = std::get_if<double>(&params[i]))
        rc = sqlite3_bind_double(raw, at, *d);
      else if (const auto* s = std::get_if<std::string>(&params[i]))
        rc = sqlite3_bind_text(raw, at, s->data(), static_cast<int>(s->size()), SQLITE_TRANSIENT);
      else
        rc = sqlite3_bind_null(raw, at);
      if (rc != SQLITE_OK) fail("{}: {} (in: {})", file_, sqlite3_errmsg(db_.get()), sql);
    }
    return stmt;
  }

  static Value column(sqlite3_stmt* stmt, int i) {
    switch (sqlite3_column_type(stmt, i)) {
      case SQLITE_INTEGER:
        return static_cast<int64_t>(sqlite3_column_int64(stmt, i));
      case SQLITE_FLOAT:
        return sqlite3_column_double(stmt, i);
      case SQLITE_NULL:
        return std::monostate{};
      default: {
        const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(stmt, i));
        return std::string(text ? text : "", static_cast<size_t>(sqlite3_column_bytes(stmt, i)));
      }
    }
  }

  std::string file_;
  DbHandle db_;
};

}  // namespace

int64_t Row::integer(size_t i) const {
  const Value& v = values_.at(i);
  if (const auto* n = std::get_if<int64_t>(&v)) return *n;
  if (const auto* d = std::get_if<double>(&v)) return static_cast<int64_t>(*d);
  if (const auto* s = std::get_if<std::string>(&v)) {
    int64_t out = 0;
    std::from_chars(s->data(), s->data() + s->size(), out);
    return out;
  }
  return 0;
}

double Row::real(size_t i) const {
  const Value& v = values_.at(i);
  if (const auto* d = std::get_if<double>(&v)) return *d;
  if (const auto* n = std::get_if<int64_t>(&v)) return static_cast<double>(*n);
  if (const auto* s = std::get_if<std::string>(&v)) return std::stod(*s);
  return 0.0;
}

std::string Row::text(size_t i) const {
  const Value& v = values_.at(i);
  if (const auto* s = std::get_if<std::string>(&v)) return *s;
  if (const auto* n = std::get_if<int64_t>(&v)) return std::to_string(*n);
  if (const auto* d = std::get_if<double>(&v)) return fmt::format("{}", *d);
  return "";
}

std::unique_ptr<Connection> openSqlite(const std::string& file) {
  return std::make_unique<SqliteConnection>(file);
}

}  // namespace xgauge::sql
