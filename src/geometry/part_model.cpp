#include "xgauge/geometry/part_model.h"

#include "expression.h"
#include "face_moves.h"
#include "solid.h"

#include "xgauge/core/config.h"
#include "xgauge/geometry/mesh.h"
#include "xgauge/geometry/step.h"
#include "xgauge/geometry/stl.h"

#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <set>

namespace xgauge {

// What the file says, with the topology fixed at nominal values. Immutable
// once built; shared by copies of a PartModel.
struct PartModel::Definition {
  struct Constraint {
    ExpressionSource expr;  // valid when > 0
    std::string message;
  };

  std::string name;  // the file name without extension
  std::string description;
  std::vector<Dimension> dimensions;
  std::vector<DeclaredCombination> combinations;
  // Variables: the dimension names, then the derived names.
  Symbols symbols;
  std::vector<ExpressionSource> derived;  // derived k sees dimensions and derived < k
  std::vector<Constraint> constraints;
  std::vector<ExpressionSource> scalars;  // the solid's, see SolidSpec
  std::unique_ptr<const Solid> shape;
  bool faced = false;  // a STEP solid whose faces the dimensions move
  std::map<std::string, std::string> shape_files;  // path -> SHA-256

  // "width=20.977 mm, thickness=13.02 mm" for error messages.
  std::string describe(std::span<const double> values) const {
    std::vector<std::string> parts;
    for (size_t i = 0; i < dimensions.size(); ++i)
      parts.push_back(fmt::format("{}={} {}", dimensions[i].name, values[i], dimensions[i].unit));
    return parts.empty() ? std::string("no dimensions") : fmt::format("{}", fmt::join(parts, ", "));
  }
};

// Compiled expressions bound to one scratch table. Built once per PartModel
// object; the table is never resized, as muparser holds its addresses.
class PartModel::Evaluator {
 public:
  explicit Evaluator(const Definition& definition)
      : scope_(definition.symbols.variables.size(), 0.0), scalars_(definition.scalars.size(), 0.0) {
    const Symbols& symbols = definition.symbols;
    const size_t dimension_count = definition.dimensions.size();
    for (size_t k = 0; k < definition.derived.size(); ++k)
      derived_.emplace_back(definition.derived[k], symbols, dimension_count + k, scope_.data());
    for (const auto& constraint : definition.constraints)
      constraints_.emplace_back(constraint.expr, symbols, scope_.size(), scope_.data());
    for (const auto& scalar : definition.scalars)
      scalar_expressions_.emplace_back(scalar, symbols, scope_.size(), scope_.data());
  }

  // Takes the dimension values, then computes the derived values and the
  // shape's scalars. Returns the first expression whose value is not finite,
  // or nullptr.
  const ExpressionSource* compute(const Definition& definition, std::span<const double> values) {
    std::copy(values.begin(), values.end(), scope_.begin());
    for (size_t k = 0; k < derived_.size(); ++k) {
      double& value = scope_[values.size() + k];
      value = derived_[k].evaluate();
      if (!std::isfinite(value)) return &definition.derived[k];
    }
    for (size_t i = 0; i < scalars_.size(); ++i) {
      scalars_[i] = scalar_expressions_[i].evaluate();
      if (!std::isfinite(scalars_[i])) return &definition.scalars[i];
    }
    return nullptr;
  }

  // Constraint i for the values of the last compute().
  double constraint(size_t i) const { return constraints_[i].evaluate(); }
  std::span<const double> scalars() const { return scalars_; }

 private:
  std::vector<double> scope_;  // dimension values, then derived values
  std::vector<double> scalars_;
  std::vector<Expression> derived_;
  std::vector<Expression> constraints_;
  std::vector<Expression> scalar_expressions_;
};

namespace {

std::string optionalString(const ConfigNode& node, std::string_view key) {
  const auto found = node.find(key);
  return found ? found->string() : std::string();
}

std::vector<double> nominalOf(const std::vector<Dimension>& dimensions) {
  std::vector<double> values;
  for (const Dimension& dimension : dimensions) values.push_back(dimension.nominal);
  return values;
}

std::string readUnit(const ConfigNode& unit) {
  std::string value = unit.string();
  if (value != "mm" && value != "deg")
    unit.fail(fmt::format("unknown unit '{}' (known: mm, deg)", value));
  return value;
}

// A name for a dimension, constant or derived value: an identifier, not a
// built-in, not taken.
std::string readName(const ConfigNode& item, std::set<std::string>& taken) {
  const ConfigNode node = item.at("name");
  std::string name = node.string();
  if (!isIdentifier(name))
    node.fail(
        fmt::format("'{}' is not a valid name: use letters, digits and '_', starting with "
                    "a letter or '_'",
                    name));
  if (isReservedName(name))
    node.fail(fmt::format("'{}' is the name of a built-in function or constant", name));
  if (!taken.insert(name).second) node.fail(fmt::format("'{}' is defined twice", name));
  return name;
}

// A dimension's "tolerance": {"lower", "upper"} deviations from nominal.
// A zone that misses [min, max] entirely is refused: no value the model can
// take could conform, which is a slip (a limit in the wrong unit) rather than
// a specification.
DimensionTolerance readTolerance(const ConfigNode& node, const Dimension& dimension) {
  DimensionTolerance tolerance;
  tolerance.lower = node.get<double>("lower");
  tolerance.upper = node.get<double>("upper");
  if (!(tolerance.lower < tolerance.upper))
    node.fail(fmt::format("lower ({}) must be below upper ({})", tolerance.lower, tolerance.upper));
  const double low = dimension.nominal + tolerance.lower;
  const double high = dimension.nominal + tolerance.upper;
  if (high < dimension.min || low > dimension.max)
    node.fail(fmt::format(
        "the tolerance zone [{}, {}] {} lies outside the dimension's [min, max] = [{}, {}]", low,
        high, dimension.unit, dimension.min, dimension.max));
  return tolerance;
}

}  // namespace

PartModel::PartModel(std::shared_ptr<const Definition> definition,
                     std::unique_ptr<Evaluator> evaluator)
    : definition_(std::move(definition)), evaluator_(std::move(evaluator)) {}

PartModel::PartModel(const PartModel& other)
    : definition_(other.definition_), evaluator_(std::make_unique<Evaluator>(*definition_)) {}

PartModel& PartModel::operator=(const PartModel& other) {
  if (this != &other) {
    definition_ = other.definition_;
    evaluator_ = std::make_unique<Evaluator>(*definition_);
  }
  return *this;
}

PartModel::PartModel(PartModel&&) noexcept = default;
PartModel& PartModel::operator=(PartModel&&) noexcept = default;
PartModel::~PartModel() = default;

namespace {

// "combinations": [{"name", optional "description", "terms": {dimension:
// coefficient, ...}}]: at least two terms, each a dimension of the part with
// a finite non-zero coefficient; all terms in one unit.
std::vector<DeclaredCombination> readCombinations(const ConfigNode& list,
                                                  const std::vector<Dimension>& dimensions,
                                                  std::set<std::string>& taken) {
  std::vector<DeclaredCombination> out;
  for (size_t i = 0; i < list.size(); ++i) {
    const ConfigNode item = list[i];
    DeclaredCombination c;
    c.name = readName(item, taken);
    c.description = optionalString(item, "description");
    const ConfigNode terms = item.at("terms");
    std::string unit;
    for (const std::string& dimension : terms.keys()) {
      const auto found = std::find_if(dimensions.begin(), dimensions.end(),
                                      [&](const Dimension& d) { return d.name == dimension; });
      if (found == dimensions.end()) terms.at(dimension).fail("not a dimension of the part");
      const double coefficient = terms.at(dimension).number();
      if (!std::isfinite(coefficient) || coefficient == 0.0)
        terms.at(dimension).fail("a coefficient must be finite and not 0");
      if (!unit.empty() && found->unit != unit)
        terms.at(dimension).fail(fmt::format("in {}, not {} as the other terms", found->unit, unit));
      unit = found->unit;
      c.terms.emplace_back(dimension, coefficient);
    }
    if (c.terms.size() < 2) terms.fail("a combination needs at least two dimensions");
    out.push_back(std::move(c));
  }
  return out;
}

}  // namespace

PartModel PartModel::load(const std::filesystem::path& path) {
  return fromConfig(ConfigNode::loadFile(path), path);
}

PartModel PartModel::fromConfig(const ConfigNode& root, const std::filesystem::path& path) {
  auto definition = std::make_shared<Definition>();
  Definition& d = *definition;
  d.name = path.stem().string();
  d.description = root.get<std::string>("description");

  // The dimensions first: a "step" solid's faces may be moved by them.
  std::set<std::string> taken;
  FaceMoveSources faces;
  faces.where = SourceLocation::inFile(path.string());
  if (const auto dimensions = root.find("dimensions")) {
    for (size_t i = 0; i < dimensions->size(); ++i) {
      const ConfigNode item = (*dimensions)[i];
      Dimension dimension;
      dimension.name = readName(item, taken);
      dimension.nominal = item.get<double>("nominal");
      dimension.min = item.get<double>("min");
      dimension.max = item.get<double>("max");
      dimension.unit = readUnit(item.at("unit"));
      dimension.description = optionalString(item, "description");
      dimension.thesis = optionalString(item, "thesis");
      if (!(dimension.min < dimension.max))
        item.fail(fmt::format("min ({}) must be less than max ({})", dimension.min, dimension.max));
      if (dimension.nominal < dimension.min || dimension.nominal > dimension.max)
        item.fail(fmt::format("nominal {} lies outside [min, max] = [{}, {}]", dimension.nominal,
                              dimension.min, dimension.max));
      if (const auto tolerance = item.find("tolerance"))
        dimension.tolerance = readTolerance(*tolerance, dimension);
      faces.dimensions.push_back(
          {dimension.name, dimension.nominal, dimension.min, dimension.max, dimension.unit});
      readFaceMoves(item, faces);
      d.symbols.variables.push_back(dimension.name);
      d.dimensions.push_back(std::move(dimension));
    }
  }
  faces.surfaces = root.find("surfaces");

  // An STL shape, or a STEP one whose faces nothing moves, takes no dimensions.
  const SolidSpec spec = readSolidSpec(root.at("shape"), path.parent_path(), &faces);
  d.scalars = spec.scalars;
  d.faced = std::any_of(spec.pieces.begin(), spec.pieces.end(), [](const SolidSpec::Piece& p) {
    return p.shape.type == ShapeType::kFaced;
  });
  for (const SolidSpec::Piece& piece : spec.pieces)
    if (!piece.shape.file.empty()) d.shape_files[piece.shape.file.string()] = piece.shape.file_sha256;
  if (!spec.fixed_root.empty()) {
    for (const char* key : {"dimensions", "constants", "derived", "constraints", "combinations"})
      if (const auto node = root.find(key))
        node->fail(spec.fixed_root == "stl"
                       ? std::string("a part with an \"stl\" shape has no dimensions, constants, "
                                     "derived values or constraints")
                       : std::string("a part with a \"step\" shape has dimensions only where "
                                     "they name the faces they move (\"offset\", \"diameter\", "
                                     "\"position\" or \"surfaces\"; docs/your-part.md)"));
  } else {
    root.at("dimensions");  // required
    if (const auto constants = root.find("constants")) {
      for (size_t i = 0; i < constants->size(); ++i) {
        const ConfigNode item = (*constants)[i];
        std::string name = readName(item, taken);
        const double value = item.get<double>("value");
        if (const auto unit = item.find("unit")) readUnit(*unit);  // documentation only
        optionalString(item, "description");
        d.symbols.constants.emplace_back(std::move(name), value);
      }
    }
    if (const auto derived = root.find("derived")) {
      for (size_t i = 0; i < derived->size(); ++i) {
        const ConfigNode item = (*derived)[i];
        d.symbols.variables.push_back(readName(item, taken));
        d.derived.push_back(readExpression(item.at("expr")));
        optionalString(item, "description");  // documentation only
      }
    }
    if (const auto constraints = root.find("constraints")) {
      for (size_t i = 0; i < constraints->size(); ++i) {
        const ConfigNode item = (*constraints)[i];
        d.constraints.push_back(
            {readExpression(item.at("expr")), item.get<std::string>("message")});
      }
    }
    if (const auto combinations = root.find("combinations"))
      d.combinations = readCombinations(*combinations, d.dimensions, taken);
  }
  root.finish();

  // Compile, evaluate at nominal values, and fix the topology there.
  auto evaluator = std::make_unique<Evaluator>(d);
  const std::vector<double> nominal = nominalOf(d.dimensions);
  if (const ExpressionSource* bad = evaluator->compute(d, nominal))
    throw Error(fmt::format("expression '{}' is not finite at nominal values", bad->text),
                bad->where);
  d.shape = std::make_unique<const Solid>(spec, evaluator->scalars());

  PartModel model(std::move(definition), std::move(evaluator));
  try {
    model.validate(nominal);
  } catch (const Error& e) {
    throw Error("the nominal values are not valid: " + e.message(), e.where());
  }
  if (model.definition_->faced) model.requireBuildableWithinBounds(path);
  return model;
}

PartModel PartModel::fromStl(const std::filesystem::path& path) {
  std::string sha256;
  TriangleMesh mesh = readStl(path, &sha256);
  return fromFixedMesh(path, "stl", std::move(mesh), sha256);
}

PartModel PartModel::fromFile(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".stl") return fromStl(path);
  if (extension == ".step" || extension == ".stp") {
    StepSolid solid = readStepSolid(path, StepTessellation{});
    return fromFixedMesh(path, "step", std::move(solid.mesh), solid.sha256);
  }
  return load(path);
}

PartModel PartModel::fromFixedMesh(const std::filesystem::path& path, const char* type,
                                   TriangleMesh mesh, const std::string& sha256) {
  auto definition = std::make_shared<Definition>();
  definition->name = path.stem().string();
  definition->description = fmt::format("fixed mesh read from {}", path.string());
  SolidSpec spec;
  spec.where = SourceLocation::inFile(path.string());
  spec.fixed_root = type;
  SolidSpec::Piece piece;
  piece.shape.type = ShapeType::kFixed;
  piece.shape.where = spec.where;
  piece.shape.fixed = std::move(mesh);
  spec.pieces.push_back(std::move(piece));
  spec.program.push_back({Csg::Op::kPiece, 0});
  definition->shape = std::make_unique<const Solid>(spec, std::span<const double>{});
  definition->shape_files[path.string()] = sha256;
  auto evaluator = std::make_unique<Evaluator>(*definition);
  return PartModel(std::move(definition), std::move(evaluator));
}

const std::string& PartModel::name() const { return definition_->name; }
const std::string& PartModel::description() const { return definition_->description; }
const std::map<std::string, std::string>& PartModel::shapeFileDigests() const {
  return definition_->shape_files;
}
const std::vector<Dimension>& PartModel::dimensions() const { return definition_->dimensions; }
const std::vector<DeclaredCombination>& PartModel::combinations() const {
  return definition_->combinations;
}
PartModel::StepFaces PartModel::stepFaces() const {
  const auto [faced, first_triangle] = definition_->shape->facedStep();
  if (!faced) return {};
  return {&faced->solid, first_triangle};
}

const std::vector<Triangle>& PartModel::triangles() const {
  return definition_->shape->triangles();
}
size_t PartModel::vertexCount() const { return definition_->shape->vertexCount(); }
const std::shared_ptr<const Csg>& PartModel::csg() const { return definition_->shape->csg(); }

std::vector<double> PartModel::nominalValues() const { return nominalOf(definition_->dimensions); }

int PartModel::dimensionIndex(std::string_view name) const {
  const auto& dimensions = definition_->dimensions;
  for (size_t i = 0; i < dimensions.size(); ++i)
    if (dimensions[i].name == name) return static_cast<int>(i);
  std::vector<std::string_view> known;
  for (const Dimension& dimension : dimensions) known.push_back(dimension.name);
  fail("unknown dimension '{}' of part '{}' (known: {})", name, definition_->name,
       known.empty() ? std::string("none") : fmt::format("{}", fmt::join(known, ", ")));
}

namespace {

void requireWithinBounds(const Dimension& dimension, double value, const std::string& part) {
  if (!(value >= dimension.min && value <= dimension.max))
    fail("{} = {} {} is outside its bounds [{}, {}] {} (part '{}')", dimension.name, value,
         dimension.unit, dimension.min, dimension.max, dimension.unit, part);
}

}  // namespace

std::vector<double> PartModel::values(const std::map<std::string, double>& overrides) const {
  std::vector<double> result = nominalValues();
  for (const auto& [name, value] : overrides) {
    const auto index = static_cast<size_t>(dimensionIndex(name));
    requireWithinBounds(definition_->dimensions[index], value, definition_->name);
    result[index] = value;
  }
  return result;
}

// Why a part model cannot take some values: the message and where the rule
// that is broken was written.
struct PartModel::Invalidity {
  std::string message;
  SourceLocation where;
};

// One check behind validate() (throws) and invalidity() (reports).
std::optional<PartModel::Invalidity> PartModel::findInvalidity(
    std::span<const double> values) const {
  const Definition& d = *definition_;
  Evaluator& evaluator = *evaluator_;
  XG_CHECK(values.size() == d.dimensions.size(), "{} values for {} dimensions", values.size(),
           d.dimensions.size());
  for (size_t i = 0; i < values.size(); ++i) {
    const Dimension& dimension = d.dimensions[i];
    if (!(values[i] >= dimension.min && values[i] <= dimension.max))
      return Invalidity{fmt::format("{} = {} {} is outside its bounds [{}, {}] {} (part '{}')",
                                    dimension.name, values[i], dimension.unit, dimension.min,
                                    dimension.max, dimension.unit, d.name),
                        {}};
  }
  if (const ExpressionSource* bad = evaluator.compute(d, values))
    return Invalidity{
        fmt::format("expression '{}' is not finite at {}", bad->text, d.describe(values)),
        bad->where};
  for (size_t i = 0; i < d.constraints.size(); ++i) {
    const double value = evaluator.constraint(i);
    if (!(value > 0))
      return Invalidity{fmt::format("constraint violated: {} ({} = {}, must be > 0) at {}",
                                    d.constraints[i].message, d.constraints[i].expr.text, value,
                                    d.describe(values)),
                        d.constraints[i].expr.where};
  }
  return std::nullopt;
}

void PartModel::validate(std::span<const double> values) const {
  if (const auto bad = findInvalidity(values)) throw Error(bad->message, bad->where);
}

std::optional<std::string> PartModel::invalidity(std::span<const double> values) const {
  if (const auto bad = findInvalidity(values)) return bad->message;
  return std::nullopt;
}

std::optional<PartModel::Invalidity> PartModel::findFold(std::span<const double> values,
                                                         std::vector<Vec3>& out) const {
  const Definition& d = *definition_;
  XG_CHECK(values.size() == d.dimensions.size(), "{} values for {} dimensions", values.size(),
           d.dimensions.size());
  if (const ExpressionSource* bad = evaluator_->compute(d, values)) [[unlikely]]
    return Invalidity{
        fmt::format("expression '{}' is not finite at {}", bad->text, d.describe(values)),
        bad->where};
  out.resize(d.shape->vertexCount());
  d.shape->place(evaluator_->scalars(), out);
  if (auto problem = d.shape->problem(evaluator_->scalars(), out)) [[unlikely]]
    return Invalidity{fmt::format("{} at {}", problem->message, d.describe(values)),
                      problem->where};
  return std::nullopt;
}

std::optional<std::string> PartModel::tryEvaluate(std::span<const double> values,
                                                  std::vector<Vec3>& out) const {
  if (auto bad = findFold(values, out)) [[unlikely]]
    return std::move(bad->message);
  return std::nullopt;
}

void PartModel::evaluate(std::span<const double> values, std::vector<Vec3>& out) const {
  if (auto bad = findFold(values, out)) [[unlikely]]
    throw Error(bad->message, bad->where);
}

std::optional<std::string> PartModel::whyNot(std::span<const double> values,
                                             std::vector<Vec3>& scratch) const {
  if (auto invalid = invalidity(values)) return invalid;
  return tryEvaluate(values, scratch);
}

PartModel::DimensionRange PartModel::buildableRange(int index) const {
  const Dimension& dimension = definition_->dimensions.at(static_cast<size_t>(index));
  std::vector<double> values = nominalValues();
  std::vector<Vec3> scratch;
  const auto why = [&](double value) {
    values[static_cast<size_t>(index)] = value;
    return whyNot(values, scratch);
  };
  DimensionRange range;
  // Each side: out from nominal on a grid, then bisection between the last
  // value that works and the first that does not.
  for (const bool up : {false, true}) {
    const double bound = up ? dimension.max : dimension.min;
    double good = dimension.nominal, end = bound;
    std::string reason = up ? "its max" : "its min";
    for (int k = 1; k <= kRangeGridSteps; ++k) {
      const double x = dimension.nominal + (bound - dimension.nominal) * k / kRangeGridSteps;
      auto problem = why(x);
      if (!problem) {
        good = x;
        continue;
      }
      double bad = x;
      for (int step = 0; step < 50 && std::abs(bad - good) > 1e-9 * (dimension.max - dimension.min);
           ++step) {
        const double middle = 0.5 * (good + bad);
        if (auto at_middle = why(middle)) {
          bad = middle;
          problem = std::move(at_middle);
        } else {
          good = middle;
        }
      }
      end = good;
      reason = *problem;
      break;
    }
    (up ? range.high : range.low) = end;
    (up ? range.high_reason : range.low_reason) = std::move(reason);
  }
  return range;
}

void PartModel::requireBuildableWithinBounds(const std::filesystem::path& path) const {
  const std::vector<Dimension>& dimensions = definition_->dimensions;
  std::vector<Vec3> scratch;
  for (size_t i = 0; i < dimensions.size(); ++i) {
    const Dimension& dimension = dimensions[i];
    std::vector<double> values = nominalValues();
    for (int k = 0; k <= kRangeGridSteps; ++k) {
      values[i] = dimension.min + (dimension.max - dimension.min) * k / kRangeGridSteps;
      if (invalidity(values)) continue;  // outside what the constraints allow
      const auto problem = tryEvaluate(values, scratch);
      if (!problem) continue;
      const DimensionRange range = buildableRange(static_cast<int>(i));
      throw Error(
          fmt::format("dimension '{}' cannot take {} {} within its bounds [{}, {}]: {}. With the "
                      "other dimensions at nominal it can be built from {:.6g} to {:.6g} {}: set "
                      "its min and max within that, or add a constraint",
                      dimension.name, values[i], dimension.unit, dimension.min, dimension.max,
                      *problem, range.low, range.high, dimension.unit),
          SourceLocation::at(path.string(), fmt::format("/dimensions/{}", i)));
    }
  }
}

TriangleMesh PartModel::mesh(std::span<const double> values) const {
  validate(values);
  TriangleMesh mesh;
  evaluate(values, mesh.vertices);
  mesh.triangles = triangles();
  mesh.csg = csg();
  return mesh;
}

}  // namespace xgauge
