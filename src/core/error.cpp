#include "xgauge/core/error.h"

#include <cstdio>
#include <cstdlib>

namespace xgauge {

std::string SourceLocation::str() const {
  std::string out = file;
  if (!file.empty() && line > 0) {
    out += fmt::format(":{}", line);
    if (column > 0) out += fmt::format(":{}", column);
  }
  if (!key_path.empty()) {
    if (!out.empty()) out += ": ";
    out += key_path;
  }
  return out;
}

static std::string withLocation(const std::string& message, const SourceLocation& where) {
  const std::string place = where.str();
  return place.empty() ? message : place + ": " + message;
}

Error::Error(const std::string& message, SourceLocation where)
    : std::runtime_error(withLocation(message, where)),
      where_(std::move(where)),
      message_(message) {}

namespace detail {
void checkFailed(const char* expr, const char* file, int line, const std::string& message) {
  std::fprintf(stderr, "xgauge: internal error: check failed: %s at %s:%d%s%s\n", expr, file,
               line, message.empty() ? "" : ": ", message.c_str());
  std::abort();
}
}  // namespace detail

}  // namespace xgauge
