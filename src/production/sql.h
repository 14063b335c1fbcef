// The little of SQL the results store needs, over SQLite and PostgreSQL
// alike: statements with numbered parameters (?1, ?2, ... written once in
// the SQLite form; the PostgreSQL connection rewrites them as $1, $2),
// explicit transactions, rows of nulls, integers, reals and text. The store
// (store.cpp) is written once against this; each database gets a thin
// connection class. Private to src/production.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace xgauge::sql {

using Value = std::variant<std::monostate, int64_t, double, std::string>;

inline Value null() { return std::monostate{}; }
template <typename T>
Value optional(const std::optional<T>& v) {
  return v ? Value(*v) : Value(std::monostate{});
}

// One result row. PostgreSQL hands every value over as text, SQLite by
// column type; the accessors convert either way (doubles round-trip: both
// databases print the shortest exact form).
class Row {
 public:
  explicit Row(std::vector<Value> values) : values_(std::move(values)) {}
  bool isNull(size_t i) const { return std::holds_alternative<std::monostate>(values_.at(i)); }
  int64_t integer(size_t i) const;
  double real(size_t i) const;
  std::string text(size_t i) const;
  std::optional<double> optionalReal(size_t i) const {
    return isNull(i) ? std::nullopt : std::optional<double>(real(i));
  }
  std::optional<std::string> optionalText(size_t i) const {
    return isNull(i) ? std::nullopt : std::optional<std::string>(text(i));
  }

 private:
  std::vector<Value> values_;
};

enum class Dialect { kSqlite, kPostgres };

class Connection {
 public:
  virtual ~Connection() = default;
  virtual Dialect dialect() const = 0;
  // Several statements without parameters (a migration).
  virtual void script(const std::string& sql) = 0;
  // One statement; returns its rows (INSERT ... RETURNING too).
  virtual std::vector<Row> query(const std::string& sql, const std::vector<Value>& params = {}) = 0;
  // One statement; returns the number of rows it changed.
  virtual int64_t execute(const std::string& sql, const std::vector<Value>& params = {}) = 0;
  // A transaction that takes the database's write lock at once (SQLite:
  // BEGIN IMMEDIATE, so two writers never deadlock on an upgrade; PostgreSQL
  // locks by row and needs nothing more).
  virtual void begin() = 0;
  virtual void commit() = 0;
  virtual void rollback() = 0;
  // Where the store is, for messages (a file, or the URL without password).
  virtual std::string where() const = 0;
};

// Rolls back unless committed: a failure between begin and commit leaves
// the database as it was.
class Transaction {
 public:
  explicit Transaction(Connection& c) : c_(c) { c_.begin(); }
  ~Transaction() {
    if (!done_) {
      try {
        c_.rollback();
      } catch (...) {  // a destructor must not throw; the connection reports later
      }
    }
  }
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  void commit() {
    c_.commit();
    done_ = true;
  }

 private:
  Connection& c_;
  bool done_ = false;
};

std::unique_ptr<Connection> openSqlite(const std::string& file);
// Throws Error when xgauge was built without libpqxx.
std::unique_ptr<Connection> openPostgres(const std::string& url);
bool postgresAvailable();

}  // namespace xgauge::sql
