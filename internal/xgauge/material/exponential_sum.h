// The material model: the whole source-material-detector chain as a sum of
// exponentials in the path length x (mm) through the part (thesis 3.4,
// docs/method.md):
//
//   I(x) = sum_k a_k exp(-mu_k x),   a_k > 0,  sum_k a_k = 1,  mu_k >= 0,
//
// so I(0) = 1 (a normalized radiograph is 1 where nothing attenuates).
//
// JSON (keys):
//   model            "exponential_sum" | "monochromatic"
//   terms            exponential_sum: [{"weight": a_k, "mu_per_mm": mu_k}, ...]
//                    (1 to 8 terms; weights must sum to 1 within 1e-9)
//   compound         monochromatic: chemical formula or NIST name (xraylib)
//   density_g_cm3    monochromatic: density in g/cm^3
//   energy_kev       monochromatic: photon energy in keV
//   description      optional free text
//   uncertainty      optional {"transmission": u, "curve_moves": [...],
//                    "besides_curve_moves": u_rest}, see transmissionUncertainty()
//                    and curveMoves()
//   calibrated_range_mm  optional [low, high]: the paths its calibration
//                    saw; a measurement warns when its part has longer paths
//   extrapolation    optional {"path_mm": [...], "half_width": [...]}: the
//                    curve's freedom beyond that range, see extrapolation()
// A monochromatic material is one term with mu from xraylib.
#pragma once

#include "xgauge/core/config.h"

#include <array>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

struct CurveMove;

// One point of the curve's extrapolation envelope (ExponentialSum::
// extrapolation()): at path_mm beyond the calibrated range, the curve may
// lie anywhere within +-half_width (transmission) of its value.
struct ExtrapolationPoint {
  double path_mm = 0.0;
  double half_width = 0.0;
};

struct ExponentialTerm {
  double weight = 1.0;     // a_k, dimensionless
  double mu_per_mm = 0.0;  // mu_k, 1/mm
};

class ExponentialSum {
 public:
  // Validates the constraints above; throws Error otherwise.
  explicit ExponentialSum(std::vector<ExponentialTerm> terms, std::string description = {});

  static ExponentialSum fromConfig(const ConfigNode& node);  // does not call finish()
  static ExponentialSum load(const std::filesystem::path& path);
  nlohmann::json toJson() const;

  // Transmission I(x) and its derivative dI/dx for a path length in mm.
  double transmission(double path_mm) const;
  double derivative(double path_mm) const;

  const std::vector<ExponentialTerm>& terms() const { return terms_; }
  const std::string& description() const { return description_; }
  // The standard uncertainty of the transmission anywhere in the calibrated
  // range (optional key "uncertainty": {"transmission": u}; a measurement's
  // budget propagates it). Default when a file states none: 0.001, what a
  // careful wedge calibration reaches (docs/results.md).
  static constexpr double kDefaultTransmissionUncertainty = 0.001;
  double transmissionUncertainty() const { return transmission_uncertainty_; }
  void setTransmissionUncertainty(double u) { transmission_uncertainty_ = u; }
  // How the curve moves with each input of its calibration that has a
  // shape of its own (a wedge's caliper dimensions): the curve calibrated
  // with that input moved by its standard uncertainty. A wedge's thin end
  // moves the curve most at the shortest paths and hardly at all at 15 mm;
  // one transmission u for all, propagated as a scale of the rates that
  // reaches u at the worst path, laid the thin end's 0.001 on a 13 mm
  // thickness as well and made its U four times what the errors showed.
  // The budget propagates each move with its own curve, and the rest of the
  // uncertainty (curveMovesBesides(): the table's, the scatter's, what no
  // move lists) as before. Empty for a curve whose file lists none.
  const std::vector<CurveMove>& curveMoves() const;
  // The transmission uncertainty from everything but curveMoves(): with
  // the moves, transmissionUncertainty()^2 = besides^2 + sum of their
  // curve_change^2.
  double curveMovesBesides() const { return moves_besides_; }
  // Throws Error when `besides` is negative or a move is invalid.
  void setCurveMoves(std::vector<CurveMove> moves, double besides);
  // The path lengths (mm) the curve was calibrated over, when its file
  // says; beyond them it is extrapolated.
  const std::optional<std::array<double, 2>>& calibratedRange() const { return calibrated_range_; }
  void setCalibratedRange(std::optional<std::array<double, 2>> range) { calibrated_range_ = range; }
  // How far the curve may be off beyond its calibrated range (docs/method.md,
  // "The curve beyond its calibrated range"): the half-width e(x) of the
  // exponential sums its calibration's table admits, less its value at the
  // range's end, at a few paths from there on (material/extrapolation.h).
  // Empty for a file without "extrapolation" (written before it, or typed).
  const std::vector<ExtrapolationPoint>& extrapolation() const { return extrapolation_; }
  // Throws Error unless there are at least 2 points, with increasing paths
  // and finite half-widths >= 0.
  void setExtrapolation(std::vector<ExtrapolationPoint> points);
  // e(x): 0 up to the first point's path, linear between the points, and
  // beyond the last one the last one's share of the curve,
  // e_last I(x) / I(x_last). 0 everywhere without extrapolation().
  double extrapolationHalfWidth(double path_mm) const;
  // The same curve with every rate scaled by (1 + relative).
  ExponentialSum withScaledRates(double relative) const;
  // The relative scale of the rates that moves the curve by `transmission`
  // at the path in [0, longest_mm] where a scale moves it most:
  // transmission / max_x |x sum_k a_k mu_k exp(-mu_k x)| (0 when no path
  // attenuates).
  double rateScaleFor(double transmission, double longest_mm) const;

 private:
  std::vector<ExponentialTerm> terms_;
  std::string description_;
  double transmission_uncertainty_ = kDefaultTransmissionUncertainty;
  std::optional<std::array<double, 2>> calibrated_range_;
  std::vector<ExtrapolationPoint> extrapolation_;
  std::shared_ptr<const std::vector<CurveMove>> moves_;  // null: none
  double moves_besides_ = 0.0;
};

// One input of a calibration and the curve it calibrates when moved by its
// standard uncertainty (ExponentialSum::curveMoves()). In JSON:
//   {"name": "wedge thin_end", "value": 0.2, "standard_uncertainty": 0.01,
//    "unit": "mm", "curve_change": 0.001,
//    "curve": {"model": "exponential_sum", "terms": [...]}}
// curve_change: the largest difference of the two curves over the
// calibrated range.
struct CurveMove {
  std::string name, unit;
  double value = 0.0, standard_uncertainty = 0.0, curve_change = 0.0;
  ExponentialSum curve;
};

}  // namespace xgauge
