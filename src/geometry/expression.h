// Arithmetic expressions of part model files (muparser), compiled once and
// evaluated many times against named values. The functions and constants an
// expression may use are listed in xgauge/geometry/part_model.h.
#pragma once

#include "xgauge/core/config.h"
#include "xgauge/core/error.h"

#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace mu {
class Parser;
}

namespace xgauge {

// An expression as written in a file, and where.
struct ExpressionSource {
  std::string text;
  SourceLocation where;
};

// An expression (a JSON string) or a plain number standing for itself.
ExpressionSource readExpression(const ConfigNode& node);

// The names expressions may use: variables, read at evaluation time from
// caller-owned storage (variable i from storage[i]), and fixed constants.
struct Symbols {
  std::vector<std::string> variables;
  std::vector<std::pair<std::string, double>> constants;
};

// A compiled expression. Not thread-safe: muparser evaluates on a stack held
// inside the parser, and the variables' storage is shared.
class Expression {
 public:
  // Compiles `source` against the constants and the first `visible` variables
  // of `symbols`, bound to storage[0, visible). Throws Error at source.where
  // for a syntax error, an unknown name (listing the known ones), an
  // assignment or a list of several values. Evaluates once (values unread).
  Expression(const ExpressionSource& source, const Symbols& symbols, size_t visible,
             double* storage);
  Expression(Expression&&) noexcept;
  Expression& operator=(Expression&&) noexcept;
  ~Expression();

  double evaluate() const;

 private:
  std::unique_ptr<mu::Parser> parser_;
};

// Letters, digits and '_', not starting with a digit.
bool isIdentifier(std::string_view name);
// Names of the built-in functions and constants, which a value may not take.
bool isReservedName(std::string_view name);

}  // namespace xgauge
