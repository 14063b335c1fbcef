// The PostgreSQL connection, through libpqxx (Debian's libpqxx-dev, 6.x).
// Built only when CMake finds libpqxx (XGAUGE_HAVE_PQXX); otherwise
// openPostgres() says so. Several stations share one database this way: the
// store's claims are rows, so no file lock has to work across hosts.
#include "sql.h"

#include "xgauge/core/error.h"

#ifdef XGAUGE_HAVE_PQXX
#include <pqxx/pqxx>
#endif

#include <regex>

namespace xgauge::sql {

namespace {

// The URL without its password, for messages.
std::string redacted(const std::string& url) {
  static const std::regex password(R"((://[^:/@]*):[^@]*@)");
  return std::regex_replace(url, password, "$1:***@");
}

#ifdef XGAUGE_HAVE_PQXX

// ?1, ?2, ... -> $1, $2, ...: the store writes SQLite's numbered form once.
std::string numbered(const std::string& sql) {
  std::string out = sql;
  for (size_t i = 0; i + 1 < out.size(); ++i)
    if (out[i] == '?' && std::isdigit(static_cast<unsigned char>(out[i + 1]))) out[i] = '$';
  return out;
}

class PostgresConnection final : public Connection {
 public:
  explicit PostgresConnection(const std::string& url) : where_(redacted(url)) {
    try {
      connection_ = std::make_unique<pqxx::connection>(url);
    } catch (const std::exception& e) {
      fail("{}: cannot connect to the results store: {}", where_, e.what());
    }
  }

  Dialect dialect() const override { return Dialect::kPostgres; }
  std::string where() const override { return where_; }

  void script(const std::string& sql) override {
    run([&](pqxx::transaction_base& t) { t.exec(sql); });
  }

  std::vector<Row> query(const std::string& sql, const std::vector<Value>& params) override {
    std::vector<Row> rows;
    run([&](pqxx::transaction_base& t) {
      const pqxx::result r = exec(t, sql, params);
      for (const auto& row : r) {
        std::vector<Value> values;
        for (const auto& field : row)
          values.push_back(field.is_null() ? Value(std::monostate{})
                                           : Value(std::string(field.c_str(), field.size())));
        rows.emplace_back(std::move(values));
      }
    });
    return rows;
  }

  int64_t execute(const std::string& sql, const std::vector<Value>& params) override {
    int64_t changed = 0;
    run([&](pqxx::transaction_base& t) { changed = exec(t, sql, params).affected_rows(); });
    return changed;
  }

  void begin() override {
    XG_CHECK(!work_, "nested transaction");
    work_ = std::make_unique<pqxx::work>(*connection_);
  }
  void commit() override {
    XG_CHECK(work_, "commit without a transaction");
    try {
      work_->commit();
    } catch (const std::exception& e) {
      work_.reset();
      fail("{}: {}", where_, e.what());
    }
    work_.reset();
  }
  void rollback() override {
    if (work_) work_->abort();
    work_.reset();
  }

 private:
  // Inside begin() ... commit() on the open transaction, else in a
  // transaction of its own.
  template <typename F>
  void run(F&& f) {
    try {
      if (work_) {
        f(*work_);
      } else {
        pqxx::work t(*connection_);
        f(t);
        t.commit();
      }
    } catch (const Error&) {
      throw;
    } catch (const std::exception& e) {
      fail("{}: {}", where_, e.what());
    }
  }

  static pqxx::result exec(pqxx::transaction_base& t, const std::string& sql,
                           const std::vector<Value>& params) {
    std::vector<std::optional<std::string>> text;
    for (const auto& v : params) {
      if (const auto* n = std::get_if<int64_t>(&v))
        text.emplace_back(std::to_string(*n));
      else if (const auto* d = std::get_if<double>(&v))
        text.emplace_back(fmt::format("{}", *d));  // shortest exact form
      else if (const auto* s = std::get_if<std::string>(&v))
        text.emplace_back(*s);
      else
        text.emplace_back(std::nullopt);
    }
    std::vector<const char*> raw;
    for (const auto& s : text) raw.push_back(s ? s->c_str() : nullptr);
    return t.exec_params(numbered(sql), pqxx::prepare::make_dynamic_params(raw));
  }

  std::string where_;
  std::unique_ptr<pqxx::connection> connection_;
  std::unique_ptr<pqxx::work> work_;
};

#endif

}  // namespace

bool postgresAvailable() {
#ifdef XGAUGE_HAVE_PQXX
  return true;
#else
  return false;
#endif
}

std::unique_ptr<Connection> openPostgres(const std::string& url) {
#ifdef XGAUGE_HAVE_PQXX
  return std::make_unique<PostgresConnection>(url);
#else
  fail("{}: this xgauge was built without PostgreSQL (libpqxx-dev): use an SQLite file",
       redacted(url));
#endif
}

}  // namespace xgauge::sql
