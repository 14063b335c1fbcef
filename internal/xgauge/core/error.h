// Errors. Bad user input (a file, a key in a config, a pixel) throws
// xgauge::Error carrying where it came from; main() catches it once, prints
// it and exits non-zero. Broken internal invariants abort via XG_CHECK.
#pragma once

#include <fmt/format.h>

#include <stdexcept>
#include <string>

namespace xgauge {

// Where a piece of bad input came from. Every field is optional.
struct SourceLocation {
  std::string file;      // path as the user gave it
  std::string key_path;  // JSON pointer such as /dimensions/width/nominal
  int line = 0;          // 1-based, 0 = unknown
  int column = 0;        // 1-based, 0 = unknown

  static SourceLocation inFile(std::string path) {
    SourceLocation where;
    where.file = std::move(path);
    return where;
  }
  static SourceLocation at(std::string path, std::string key) {
    SourceLocation where;
    where.file = std::move(path);
    where.key_path = std::move(key);
    return where;
  }

  // "file:line:column: /key/path" with the empty parts left out.
  std::string str() const;
};

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message, SourceLocation where = {});

  const SourceLocation& where() const { return where_; }
  // The bare message without the location prefix.
  const std::string& message() const { return message_; }

 private:
  SourceLocation where_;
  std::string message_;
};

// Shorthand: throw Error(fmt::format(...)).
template <typename... Args>
[[noreturn]] void fail(fmt::format_string<Args...> format, Args&&... args) {
  throw Error(fmt::format(format, std::forward<Args>(args)...));
}
template <typename... Args>
[[noreturn]] void failAt(SourceLocation where, fmt::format_string<Args...> format,
                         Args&&... args) {
  throw Error(fmt::format(format, std::forward<Args>(args)...), std::move(where));
}

namespace detail {
[[noreturn]] void checkFailed(const char* expr, const char* file, int line,
                              const std::string& message);
}  // namespace detail

}  // namespace xgauge

// Internal invariant: aborts with the expression, place and an optional
// message. Not for user input.
#define XG_CHECK(cond, ...)                                                      \
  do {                                                                           \
    if (!(cond)) [[unlikely]]                                                    \
      ::xgauge::detail::checkFailed(#cond, __FILE__, __LINE__,                  \
                                    ::fmt::format("" __VA_ARGS__));             \
  } while (false)
