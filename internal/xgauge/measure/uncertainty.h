// The uncertainty budget of a measurement (GUM, JCGM 100:2008): for every
// free dimension, the standard uncertainty of each influence, its
// sensitivity, and the expanded uncertainty U = k u_c with k = 2.
//
// Components (docs/method.md, "Uncertainty"):
//   statistical        noise and what the model leaves unexplained in the
//                      pixels: the sandwich covariance A^-1 B A^-1 of the
//                      robust least squares, A = J^T W J and B summed over
//                      blocks of 16 x 16 pixels of the fit's level
//                      (cluster-robust), so that pixel correlation from the
//                      area sampling, the pyramid, the detector's blur and
//                      any structured misfit counts as it is in the data
//   material           the transmission curve's stated uncertainty, as a
//                      common scale of its rates that moves the curve by that
//                      much at the worst path of the part
//   scatter weight, scatter width, source-detector distance, pixel pitch,
//   translation distance (per translated radiograph)
//                      each by re-simulating at the value moved by its
//                      standard uncertainty: the linearised re-solve
//                      d theta = -A^-1 J^T W d r
// The components are taken as independent; u_c is their root sum of squares.
//
// Parameters the radiographs cannot separate show as near-null directions of
// A: a dimension with a share of one gets no U ("not identifiable"), and the
// combinations of such dimensions that are measurable are reported with their
// own U (e.g. the sum of two edges that move together with the part).
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace xgauge {

struct UncertaintyComponent {
  std::string name;             // "statistical", "material", ...
  std::string quantity;         // what is uncertain, in words with its value
  double standard_uncertainty;  // u(q) of the influence, in `unit`
  std::string unit;             // of u(q)
  double sensitivity;           // d value / d q (dimension unit per `unit`); 1 for statistical
  double contribution;          // |sensitivity| u(q), in the dimension's unit
};

struct DimensionUncertainty {
  std::string name;
  bool identifiable = true;
  std::vector<UncertaintyComponent> components;
  double combined = 0.0;  // u_c
  double expanded = 0.0;  // U = k u_c (0 and meaningless when not identifiable)
};

// A sum or difference of dimensions measured better than its terms: one the
// part model declares (named; any coefficients), or a pair of dimensions the
// budget found so strongly correlated that their sum or difference is (no
// name; coefficients +-1). U is 0 where the radiographs do not determine it.
struct MeasurableCombination {
  std::string name;                                   // the part model's; empty when found
  std::vector<std::pair<std::string, double>> terms;  // (dimension, coefficient)
  std::string expression;                             // "pocket_left + pocket_right"
  double value = 0.0;
  double expanded = 0.0;  // U, k = 2
};

// The material's curve refined in situ (job "refine_material"): the rate
// scale e the radiographs chose (the curve used is the material's with every
// rate times 1 + e), the prior it was weighed by, its standard uncertainty as
// the radiographs determine it (the budget's statistical part and every
// influence but the material's own, which move the curve e corrects and e
// with it, leaving the refined curve in place), and what it does
// to the curve: the largest change of the transmission over the part's
// paths, signed, and the path where it happens.
struct MaterialRefinementResult {
  double rate_scale = 0.0;
  double prior_standard_uncertainty = 0.0;
  double standard_uncertainty = 0.0;
  double transmission_change = 0.0;
  double at_path_mm = 0.0;
};

struct UncertaintyBudget {
  double coverage_factor = 2.0;
  int level = 0;                                 // pyramid level of the linearisation
  double pixels = 0.0;                           // residuals used
  std::vector<DimensionUncertainty> dimensions;  // the free dimensions, model order
  std::vector<MeasurableCombination> combinations;
  std::optional<MaterialRefinementResult> refinement;
  std::vector<std::string> notes;  // why a component is missing, and the like
  // The influences whose shift could not be found (their propagation
  // failed): left out of U, which is then smaller than it should be.
  std::vector<std::string> unpropagated;
};

}  // namespace xgauge
