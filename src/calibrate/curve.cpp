#include "xgauge/calibrate/curve.h"

#include "xgauge/core/error.h"
#include "xgauge/material/attenuation.h"
#include "xgauge/material/extrapolation.h"

#include <algorithm>
#include <cmath>
#include <functional>

namespace xgauge {

RateFloor RateFloor::fromConfig(const ConfigNode& node) {
  RateFloor out;
  out.compound = node.get<std::string>("compound");
  out.density_g_cm3 = node.at("density_g_cm3").number(1e-6, 30.0);
  out.tube_kv = node.at("tube_kv").number(5.0, 1000.0);
  try {
    out.per_mm = attenuationFloorPerMm(out.compound, out.density_g_cm3, out.tube_kv);
  } catch (const Error& e) {
    node.at("compound").fail(e.message());
  }
  return out;
}

nlohmann::json RateFloor::toJson() const {
  return {{"compound", compound},
          {"density_g_cm3", density_g_cm3},
          {"tube_kv", tube_kv},
          {"per_mm", per_mm}};
}

double CurveFit::tableUncertainty() const {
  const TermsFit& f = best();
  const double rms = f.report.rms_residual;
  // Free parameters: a weight and a rate per term, one weight fewer when
  // they sum to 1 (no way to tell here; count them all, the larger).
  const double p = 2.0 * f.report.terms_used;
  const double statistical =
      points > 0 ? noise * std::sqrt(std::min(1.0, p / static_cast<double>(points))) : noise;
  const double misfit = std::sqrt(std::max(0.0, rms * rms - noise * noise));
  return std::hypot(statistical, misfit);
}

CurveFit fitCurve(std::span<const double> path_mm, std::span<const double> transmission,
                  const CurveOptions& curve, const std::string& what, CurveFit* tried) {
  const int max_terms = curve.max_terms;
  const double noise = curve.noise;
  if (max_terms < 1 || max_terms > 4) fail("{}: max_terms must be 1 to 4, got {}", what, max_terms);
  CurveFit out;
  out.rate_floor_per_mm = curve.rate_floor_per_mm;
  out.points = path_mm.size();
  out.noise = noise;
  ExponentialFitOptions options;
  options.free_amplitude = curve.free_amplitude;
  options.min_mu_per_mm = curve.rate_floor_per_mm;
  options.max_transmission = 2.0;  // measured: noise may lift a value above 1
  for (int m = 1; m <= max_terms; ++m) {
    TermsFit fit;
    fit.terms = m;
    try {
      fit.fitted = fitExponentialTerms(path_mm, transmission, m, options, &fit.report);
    } catch (const Error& e) {
      if (tried) *tried = out;
      fail("{}: {}", what, e.message());
    }
    out.fits.push_back(std::move(fit));
  }
  double best_rms = HUGE_VAL;
  for (const TermsFit& f : out.fits) best_rms = std::min(best_rms, f.report.rms_residual);
  bool within_noise = false;
  for (size_t k = 0; k < out.fits.size() && !within_noise; ++k)
    if (out.fits[k].report.rms_residual <= 1.25 * noise) out.chosen = k, within_noise = true;
  if (within_noise) {
    out.choice =
        fmt::format("smallest M whose rms residual ({:.3g}) is within 1.25 x the noise ({:.3g})",
                    out.best().report.rms_residual, noise);
  } else {
    for (size_t k = 0; k < out.fits.size(); ++k)
      if (out.fits[k].report.rms_residual <= 1.1 * best_rms) {
        out.chosen = k;
        break;
      }
    out.choice = fmt::format(
        "no M fits within the noise ({:.3g}); smallest M within 10 % of the best rms residual "
        "({:.3g})",
        noise, best_rms);
  }
  const ExponentialFitReport& r = out.best().report;
  if (tried) *tried = out;
  if (!(r.max_relative_residual <= curve.max_relative_residual))
    fail(
        "{}: the exponential fit does not converge to the data: with {} terms its residual reaches "
        "{:.1f} % "
        "of the intensity (rms {:.3g}); check the ramp rows, the white region and that the table "
        "falls "
        "with the path",
        what, out.best().terms, 100.0 * r.max_relative_residual, r.rms_residual);
  return out;
}

nlohmann::json toJson(const CurveFit& fit) {
  nlohmann::json fits = nlohmann::json::array();
  for (const TermsFit& f : fit.fits) {
    nlohmann::json terms = nlohmann::json::array();
    double sum = 0.0;
    for (const ExponentialTerm& t : f.fitted) {
      terms.push_back({{"weight", t.weight}, {"mu_per_mm", t.mu_per_mm}});
      sum += t.weight;
    }
    fits.push_back({{"terms_asked", f.terms},
                    {"terms_used", f.report.terms_used},
                    {"rms_residual", f.report.rms_residual},
                    {"max_abs_residual", f.report.max_abs_residual},
                    {"max_relative_residual", f.report.max_relative_residual},
                    {"weight_sum", sum},
                    {"terms", terms}});
  }
  return {{"fits", fits},
          {"chosen_terms", fit.best().terms},
          {"choice", fit.choice},
          {"rate_floor_per_mm", fit.rate_floor_per_mm},
          {"table_uncertainty", fit.tableUncertainty()}};
}

void addExtrapolation(ExponentialSum& material, std::span<const double> path_mm,
                      std::span<const double> transmission, const CurveFit& fit) {
  if (!(fit.noise > 0.0) || path_mm.size() < 4) return;
  material.setExtrapolation(
      extrapolationEnvelope(path_mm, transmission, fit.noise, fit.rate_floor_per_mm, material)
          .points);
}

double TrueCurve::operator()(double x) const {
  XG_CHECK(path_mm.size() >= 2 && path_mm.size() == transmission.size(), "bad true curve");
  const auto it = std::upper_bound(path_mm.begin(), path_mm.end(), x);
  const size_t i =
      std::clamp<size_t>(static_cast<size_t>(it - path_mm.begin()), 1, path_mm.size() - 1);
  const double t = (x - path_mm[i - 1]) / (path_mm[i] - path_mm[i - 1]);
  return transmission[i - 1] + t * (transmission[i] - transmission[i - 1]);
}

CurveDeviation curveDeviation(const std::function<double(double)>& a,
                              const std::function<double(double)>& b, double max_path_mm) {
  CurveDeviation out;
  const int steps = static_cast<int>(std::ceil(max_path_mm / 0.01));
  for (int i = 0; i <= steps; ++i) {
    const double x = std::min(max_path_mm, 0.01 * i);
    const double d = std::abs(a(x) - b(x));
    if (d > out.max_abs) out.max_abs = d, out.at_mm = x;
  }
  return out;
}

double largestDifference(const ExponentialSum& a, const ExponentialSum& b, double max_path_mm) {
  return curveDeviation([&](double x) { return a.transmission(x); },
                        [&](double x) { return b.transmission(x); }, max_path_mm)
      .max_abs;
}

}  // namespace xgauge
