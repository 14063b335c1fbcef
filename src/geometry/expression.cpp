#include "expression.h"

#include "xgauge/core/transform.h"

#include <fmt/ranges.h>
#include <muParser.h>

#include <cmath>
#include <numbers>

namespace xgauge {
namespace {

// Helpers for angles in degrees (muparser's trigonometry takes radians).
double rad(double degrees) { return degrees * kDegToRad; }
double deg(double radians) { return radians * kRadToDeg; }
double sind(double degrees) { return std::sin(degrees * kDegToRad); }
double cosd(double degrees) { return std::cos(degrees * kDegToRad); }
double tand(double degrees) { return std::tan(degrees * kDegToRad); }
double asind(double x) { return std::asin(x) * kRadToDeg; }
double acosd(double x) { return std::acos(x) * kRadToDeg; }
double atand(double x) { return std::atan(x) * kRadToDeg; }
double atan2d(double y, double x) { return std::atan2(y, x) * kRadToDeg; }

std::unique_ptr<mu::Parser> newParser() {
  auto parser = std::make_unique<mu::Parser>();
  parser->DefineFun("rad", rad);
  parser->DefineFun("deg", deg);
  parser->DefineFun("sind", sind);
  parser->DefineFun("cosd", cosd);
  parser->DefineFun("tand", tand);
  parser->DefineFun("asind", asind);
  parser->DefineFun("acosd", acosd);
  parser->DefineFun("atand", atand);
  parser->DefineFun("atan2d", atan2d);
  parser->DefineConst("pi", std::numbers::pi);
  return parser;
}

// muparser's "=" assigns to a variable; an expression must only read.
bool hasAssignment(std::string_view text) {
  for (size_t i = 0; i < text.size(); ++i) {
    if (text[i] != '=') continue;
    const bool comparison =
        (i > 0 && std::string_view("<>!=").find(text[i - 1]) != std::string_view::npos) ||
        (i + 1 < text.size() && text[i + 1] == '=');
    if (!comparison) return true;
  }
  return false;
}

}  // namespace

ExpressionSource readExpression(const ConfigNode& node) {
  if (node.isNumber()) return {fmt::format("{}", node.number()), node.where()};
  if (!node.isString()) node.fail("expected an expression (a string) or a number");
  return {node.string(), node.where()};
}

Expression::Expression(const ExpressionSource& source, const Symbols& symbols, size_t visible,
                       double* storage)
    : parser_(newParser()) {
  auto bad = [&](const std::string& why) {
    throw Error(fmt::format("bad expression '{}': {}", source.text, why), source.where);
  };
  if (hasAssignment(source.text)) bad("'=' assigns; compare with '==' or remove it");
  try {
    for (const auto& [name, value] : symbols.constants) parser_->DefineConst(name, value);
    for (size_t i = 0; i < visible; ++i) parser_->DefineVar(symbols.variables[i], storage + i);
    parser_->SetExpr(source.text);
    parser_->Eval();  // muparser parses on the first evaluation
  } catch (const mu::Parser::exception_type& e) {
    std::string why = e.GetMsg();
    if (e.GetPos() >= 0 && why.find("position") == std::string::npos)
      why += fmt::format(" (position {})", e.GetPos());
    if (e.GetCode() == mu::ecUNASSIGNABLE_TOKEN) {
      std::vector<std::string> known(
          symbols.variables.begin(),
          symbols.variables.begin() + static_cast<std::ptrdiff_t>(visible));
      for (const auto& constant : symbols.constants) known.push_back(constant.first);
      why += fmt::format(" (known names: {})", fmt::join(known, ", "));
    }
    bad(why);
  }
  if (parser_->GetNumResults() != 1)
    bad(fmt::format("it gives {} values separated by ',', not one", parser_->GetNumResults()));
}

Expression::Expression(Expression&&) noexcept = default;
Expression& Expression::operator=(Expression&&) noexcept = default;
Expression::~Expression() = default;

double Expression::evaluate() const { return parser_->Eval(); }

bool isIdentifier(std::string_view name) {
  auto letter = [](char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_'; };
  if (name.empty() || !letter(name.front())) return false;
  for (char c : name)
    if (!letter(c) && !(c >= '0' && c <= '9')) return false;
  return true;
}

bool isReservedName(std::string_view name) {
  static const std::unique_ptr<mu::Parser> reference = newParser();
  const std::string key(name);
  return reference->GetFunDef().count(key) > 0 || reference->GetConst().count(key) > 0;
}

}  // namespace xgauge
