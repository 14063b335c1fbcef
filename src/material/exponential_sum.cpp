#include "xgauge/material/exponential_sum.h"

#include "xgauge/material/attenuation.h"

#include <algorithm>
#include <cmath>

namespace xgauge {

ExponentialSum::ExponentialSum(std::vector<ExponentialTerm> terms, std::string description)
    : terms_(std::move(terms)), description_(std::move(description)) {
  if (terms_.empty() || terms_.size() > 8)
    fail("an exponential-sum material needs 1 to 8 terms, got {}", terms_.size());
  double sum = 0.0;
  for (size_t k = 0; k < terms_.size(); ++k) {
    const auto& t = terms_[k];
    if (!(t.weight > 0.0) || !std::isfinite(t.weight))
      fail("term {}: weight must be positive, got {}", k, t.weight);
    if (!(t.mu_per_mm >= 0.0) || !std::isfinite(t.mu_per_mm))
      fail("term {}: mu_per_mm must be >= 0, got {}", k, t.mu_per_mm);
    sum += t.weight;
  }
  if (std::abs(sum - 1.0) > 1e-9) fail("weights must sum to 1, they sum to {:.12g}", sum);
}

ExponentialSum ExponentialSum::fromConfig(const ConfigNode& node) {
  const std::string model = node.get<std::string>("model");
  const std::string description = node.get<std::string>("description", "");
  double uncertainty = kDefaultTransmissionUncertainty;
  std::vector<CurveMove> moves;
  double besides = 0.0;
  if (auto u = node.find("uncertainty")) {
    uncertainty = u->at("transmission").number(0.0, 0.5);
    if (auto list = u->find("curve_moves")) {
      besides = u->at("besides_curve_moves").number(0.0, 0.5);
      for (size_t i = 0; i < list->size(); ++i) {
        const ConfigNode move = (*list)[i];
        const ConfigNode curve = move.at("curve");
        moves.push_back({move.get<std::string>("name"), move.get<std::string>("unit"),
                         move.at("value").number(), move.at("standard_uncertainty").number(0.0, 1e6),
                         move.at("curve_change").number(0.0, 1.0), fromConfig(curve)});
        if (!(moves.back().standard_uncertainty > 0.0))
          move.at("standard_uncertainty").fail("expected a positive standard uncertainty");
      }
    }
  }
  // A wedge calibration's detector scatter (calibrate/wedge.h): read by the
  // measurement that uses the material (measure/inputs.cpp), not by the curve.
  static_cast<void>(node.find("scatter"));
  std::optional<std::array<double, 2>> range;
  if (auto r = node.find("calibrated_range_mm")) {
    if (r->size() != 2) r->fail("calibrated_range_mm: expected [low, high] in mm");
    range = std::array<double, 2>{(*r)[0].number(0.0, 1e5), (*r)[1].number(0.0, 1e5)};
    if (!((*range)[0] < (*range)[1]))
      r->fail(fmt::format("calibrated_range_mm: low ({}) must be below high ({})", (*range)[0],
                          (*range)[1]));
  }
  std::vector<ExtrapolationPoint> extrapolation;
  if (auto e = node.find("extrapolation")) {
    const ConfigNode paths = e->at("path_mm"), widths = e->at("half_width");
    if (paths.size() != widths.size() || paths.size() < 2)
      e->fail(fmt::format(
          "extrapolation: expected path_mm and half_width of the same length, at least 2 (got {} "
          "and {})",
          paths.size(), widths.size()));
    for (size_t i = 0; i < paths.size(); ++i) {
      extrapolation.push_back({paths[i].number(0.0, 1e6), widths[i].number(0.0, 1.0)});
      if (i > 0 && !(extrapolation[i].path_mm > extrapolation[i - 1].path_mm))
        paths[i].fail("extrapolation: path_mm must increase");
    }
  }
  try {
    if (model == "exponential_sum") {
      const ConfigNode list = node.at("terms");
      std::vector<ExponentialTerm> terms;
      for (size_t i = 0; i < list.size(); ++i) {
        const ConfigNode term = list[i];
        terms.push_back({term.at("weight").number(), term.at("mu_per_mm").number()});
      }
      // A material file must describe something that attenuates: with every
      // rate 0, a measurement would return its start values unchanged.
      if (std::all_of(terms.begin(), terms.end(),
                      [](const ExponentialTerm& t) { return t.mu_per_mm == 0.0; }))
        list.fail(
            "every mu_per_mm is 0: the material would not attenuate, and no dimension "
            "could be measured");
      ExponentialSum out(std::move(terms), description);
      out.transmission_uncertainty_ = uncertainty;
      out.calibrated_range_ = range;
      out.extrapolation_ = extrapolation;
      if (!moves.empty()) out.setCurveMoves(std::move(moves), besides);
      return out;
    }
    if (model == "monochromatic") {
      const std::string compound = node.get<std::string>("compound");
      const double density = node.at("density_g_cm3").number(1e-6, 30.0);
      const double energy = node.at("energy_kev").number(1.0, 1000.0);
      ExponentialSum out({{1.0, linearAttenuationPerMm(compound, density, energy)}},
                         description.empty()
                             ? fmt::format("{} ({} g/cm^3) at {} keV", compound, density, energy)
                             : description);
      out.transmission_uncertainty_ = uncertainty;
      out.calibrated_range_ = range;
      out.extrapolation_ = extrapolation;
      if (!moves.empty()) out.setCurveMoves(std::move(moves), besides);
      return out;
    }
  } catch (const Error& e) {
    if (!e.where().file.empty()) throw;
    node.fail(e.message());
  }
  node.at("model").fail(
      fmt::format("unknown material model '{}' (known: exponential_sum, monochromatic)", model));
}

ExponentialSum ExponentialSum::load(const std::filesystem::path& path) {
  const ConfigNode root = ConfigNode::loadFile(path);
  ExponentialSum material = fromConfig(root);
  root.finish();
  return material;
}

nlohmann::json ExponentialSum::toJson() const {
  nlohmann::json terms = nlohmann::json::array();
  for (const auto& t : terms_) terms.push_back({{"weight", t.weight}, {"mu_per_mm", t.mu_per_mm}});
  nlohmann::json out = {{"model", "exponential_sum"}, {"terms", terms}};
  if (!description_.empty()) out["description"] = description_;
  out["uncertainty"] = {{"transmission", transmission_uncertainty_}};
  if (moves_) {
    nlohmann::json moves = nlohmann::json::array();
    for (const CurveMove& move : *moves_) {
      const nlohmann::json curve = move.curve.toJson();
      moves.push_back({{"name", move.name},
                       {"value", move.value},
                       {"standard_uncertainty", move.standard_uncertainty},
                       {"unit", move.unit},
                       {"curve_change", move.curve_change},
                       {"curve", {{"model", curve.at("model")}, {"terms", curve.at("terms")}}}});
    }
    out["uncertainty"]["curve_moves"] = moves;
    out["uncertainty"]["besides_curve_moves"] = moves_besides_;
  }
  if (calibrated_range_) out["calibrated_range_mm"] = *calibrated_range_;
  if (!extrapolation_.empty()) {
    nlohmann::json paths = nlohmann::json::array(), widths = nlohmann::json::array();
    for (const ExtrapolationPoint& p : extrapolation_)
      paths.push_back(p.path_mm), widths.push_back(p.half_width);
    out["extrapolation"] = {{"path_mm", paths}, {"half_width", widths}};
  }
  return out;
}

void ExponentialSum::setExtrapolation(std::vector<ExtrapolationPoint> points) {
  if (points.size() == 1) fail("a curve's extrapolation needs at least 2 points, got 1");
  for (size_t i = 0; i < points.size(); ++i) {
    const ExtrapolationPoint& p = points[i];
    if (!(p.path_mm >= 0.0) || !std::isfinite(p.path_mm) || !(p.half_width >= 0.0) ||
        !std::isfinite(p.half_width))
      fail("extrapolation point {}: path {} mm and half-width {} must be finite and >= 0", i,
           p.path_mm, p.half_width);
    if (i > 0 && !(p.path_mm > points[i - 1].path_mm))
      fail("extrapolation point {}: its path ({} mm) must exceed the one before ({} mm)", i,
           p.path_mm, points[i - 1].path_mm);
  }
  extrapolation_ = std::move(points);
}

double ExponentialSum::extrapolationHalfWidth(double path_mm) const {
  if (extrapolation_.empty() || !(path_mm > extrapolation_.front().path_mm)) return 0.0;
  const auto next =
      std::upper_bound(extrapolation_.begin(), extrapolation_.end(), path_mm,
                       [](double x, const ExtrapolationPoint& p) { return x < p.path_mm; });
  if (next == extrapolation_.end()) {
    const ExtrapolationPoint& last = extrapolation_.back();
    const double at = transmission(last.path_mm);
    return at > 0.0 ? last.half_width * transmission(path_mm) / at : last.half_width;
  }
  const ExtrapolationPoint& b = *next;
  const ExtrapolationPoint& a = *(next - 1);
  const double t = (path_mm - a.path_mm) / (b.path_mm - a.path_mm);
  return a.half_width + t * (b.half_width - a.half_width);
}

const std::vector<CurveMove>& ExponentialSum::curveMoves() const {
  static const std::vector<CurveMove> kNone;
  return moves_ ? *moves_ : kNone;
}

void ExponentialSum::setCurveMoves(std::vector<CurveMove> moves, double besides) {
  if (!(besides >= 0.0) || !std::isfinite(besides))
    fail("the curve's uncertainty besides its moves must be >= 0, got {}", besides);
  for (const CurveMove& move : moves)
    if (!(move.standard_uncertainty > 0.0) || !(move.curve_change >= 0.0))
      fail("curve move '{}': its standard uncertainty must be positive and its change >= 0",
           move.name);
  moves_besides_ = besides;
  moves_ =
      moves.empty() ? nullptr : std::make_shared<const std::vector<CurveMove>>(std::move(moves));
}

double ExponentialSum::rateScaleFor(double transmission, double longest_mm) const {
  double slope = 0.0;
  constexpr int kSteps = 400;
  for (int k = 0; k <= kSteps; ++k) {
    const double x = longest_mm * k / kSteps;
    double d = 0.0;
    for (const auto& t : terms_) d += t.weight * t.mu_per_mm * std::exp(-t.mu_per_mm * x);
    slope = std::max(slope, x * d);
  }
  return slope > 0.0 ? transmission / slope : 0.0;
}

ExponentialSum ExponentialSum::withScaledRates(double relative) const {
  std::vector<ExponentialTerm> terms = terms_;
  for (auto& t : terms) t.mu_per_mm *= 1.0 + relative;
  ExponentialSum out(std::move(terms), description_);
  out.transmission_uncertainty_ = transmission_uncertainty_;
  out.calibrated_range_ = calibrated_range_;
  out.extrapolation_ = extrapolation_;
  out.moves_ = moves_;
  out.moves_besides_ = moves_besides_;
  return out;
}

double ExponentialSum::transmission(double path_mm) const {
  double sum = 0.0;
  for (const auto& t : terms_) sum += t.weight * std::exp(-t.mu_per_mm * path_mm);
  return sum;
}

double ExponentialSum::derivative(double path_mm) const {
  double sum = 0.0;
  for (const auto& t : terms_) sum -= t.weight * t.mu_per_mm * std::exp(-t.mu_per_mm * path_mm);
  return sum;
}

}  // namespace xgauge
