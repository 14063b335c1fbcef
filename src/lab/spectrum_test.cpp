#include "xgauge/lab/spectrum.h"

#include "xgauge/material/attenuation.h"

#include <gtest/gtest.h>
#include <xraylib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>

namespace xgauge {
namespace {

const Layer kAluminium = {"Al", 2.699, 0.0};

// Photons in the K lines: the tungsten spectrum minus its continuum, bins
// above 50 keV (the L lines lie below 13 keV).
double kLinePhotons(double tube_kv) {
  const Spectrum lines = Spectrum::tungsten(tube_kv);
  const Spectrum continuum = Spectrum::kramers(tube_kv);
  return lines.photonsBetween(50.0, 1e9) - continuum.photonsBetween(50.0, 1e9);
}

TEST(Spectrum, KramersContinuumIsZeroAboveTheTubeVoltage) {
  const Spectrum s = Spectrum::kramers(100.0, 0.5, 150.0);
  ASSERT_GT(s.size(), 0u);
  EXPECT_NEAR(s.energiesKev().back(), 149.75, 1e-12);
  for (size_t i = 0; i < s.size(); ++i) {
    if (s.lowerEdgeKev(i) >= 100.0) {
      EXPECT_EQ(s.photons()[i], 0.0) << s.energiesKev()[i] << " keV";
    } else {
      EXPECT_GT(s.photons()[i], 0.0) << s.energiesKev()[i] << " keV";
    }
  }
  // Bins hold exact integrals: their sum is int_1^E0 (E0/E - 1) dE.
  EXPECT_NEAR(s.totalPhotons(), 100.0 * std::log(100.0) - 99.0, 1e-9);
  // Falls with energy, as (E0 - E) / E does.
  for (size_t i = 1; s.lowerEdgeKev(i) < 100.0; ++i) EXPECT_LT(s.photons()[i], s.photons()[i - 1]);
}

TEST(Spectrum, KLinesOnlyAboveTheKEdge) {
  const double k_edge_kev = EdgeEnergy(74, K_SHELL, nullptr);
  const double ka1_kev = LineEnergy(74, KA1_LINE, nullptr);
  EXPECT_NEAR(ka1_kev, 59.3, 0.1);
  EXPECT_GT(k_edge_kev, 60.0);

  // 60 kV is below the K edge: above 20 keV the spectrum is pure continuum.
  const Spectrum low = Spectrum::tungsten(60.0);
  const Spectrum low_continuum = Spectrum::kramers(60.0);
  for (size_t i = 0; i < low.size(); ++i) {
    if (low.energiesKev()[i] > 20.0) {
      EXPECT_EQ(low.photons()[i], low_continuum.photons()[i]);
    }
  }
  // ... but the L lines are there (above the L3 edge, 10.2 keV).
  const size_t la1 = low.binOf(LineEnergy(74, LA1_LINE, nullptr));
  ASSERT_LT(la1, low.size());
  EXPECT_GT(low.photons()[la1], 2.0 * low_continuum.photons()[la1]);

  // 150 kV: a Kalpha1 peak in the bin holding xraylib's energy, well above
  // the continuum, and the strongest K line.
  const Spectrum high = Spectrum::tungsten(150.0);
  const Spectrum high_continuum = Spectrum::kramers(150.0);
  const size_t i = high.binOf(ka1_kev);
  ASSERT_LT(i, high.size());
  EXPECT_LE(high.lowerEdgeKev(i), ka1_kev);
  EXPECT_GT(high.lowerEdgeKev(i) + high.binKev(), ka1_kev);
  EXPECT_GT(high.photons()[i], 3.0 * high_continuum.photons()[i]);
  double strongest_k = 0.0;
  int strongest_line = 0;
  for (const EmissionLine& line : tungstenLines(150.0))
    if (line.energy_kev > 50.0 && line.photons > strongest_k)
      strongest_k = line.photons, strongest_line = line.xraylib_line;
  EXPECT_EQ(strongest_line, KA1_LINE);
}

TEST(Spectrum, KLineFractionIsPlausibleAndGrowsWithVoltage) {
  const double fraction_150 =
      kLinePhotons(150.0) / Spectrum::tungsten(150.0).photonsBetween(50.0, 1e9);
  EXPECT_GT(fraction_150, 0.05);
  EXPECT_LT(fraction_150, 0.15);
  const double fraction_220 =
      kLinePhotons(220.0) / Spectrum::tungsten(220.0).photonsBetween(50.0, 1e9);
  std::printf("K lines / photons above 50 keV: %.3f at 150 kV, %.3f at 220 kV\n", fraction_150,
              fraction_220);
  EXPECT_GT(fraction_220, fraction_150);
  EXPECT_EQ(kLinePhotons(69.0), 0.0);  // just below the K edge
  EXPECT_GT(kLinePhotons(70.0), 0.0);  // just above it
}

TEST(Spectrum, FilterFollowsBeerLambertAndHardens) {
  const Spectrum open = Spectrum::tungsten(150.0);
  Spectrum filtered = open;
  const Layer copper = {"Cu", 8.96, 1.0};
  filtered.filter(copper);
  for (size_t i = 0; i < open.size(); i += 37) {
    const double e = open.energiesKev()[i];
    EXPECT_NEAR(filtered.photons()[i],
                open.photons()[i] * std::exp(-linearAttenuationPerMm("Cu", 8.96, e)), 1e-12);
  }
  EXPECT_GT(filtered.meanEnergyKev(), open.meanEnergyKev() + 20.0);
  EXPECT_LT(filtered.totalPhotons(), open.totalPhotons());
  // A zero-thickness layer changes nothing.
  Spectrum same = open;
  same.filter({"Cu", 8.96, 0.0});
  EXPECT_EQ(same.photons(), open.photons());
}

TEST(BeamModel, DetectorWeightsFollowTheFormula) {
  const BeamModel beam;  // thesis defaults
  const Spectrum s = beam.spectrum();
  const auto w = beam.detectorWeights();
  ASSERT_EQ(w.size(), s.size());
  for (size_t i = 0; i < s.size(); i += 29) {
    const double e = s.energiesKev()[i];
    const double expected = s.photons()[i] *
                            std::exp(-linearAttenuationPerMm("Al", 2.699, e) * 0.5) * e *
                            (1.0 - std::exp(-linearAttenuationPerMm("CsI", 4.51, e) * 0.6));
    EXPECT_NEAR(w[i], expected, 1e-12 * std::max(1.0, expected));
  }
}

TEST(PolychromaticMaterial, MonochromaticBeamIsBeerLambert) {
  const PolychromaticMaterial mono({80.25}, {3.0}, kAluminium);
  const double mu = linearAttenuationPerMm("Al", 2.699, 80.25);
  for (double x : {0.0, 1.0, 17.5, 60.0}) {
    EXPECT_NEAR(mono.transmission(x), std::exp(-mu * x), 1e-15);
    EXPECT_NEAR(mono.effectiveMuPerMm(x), mu, 1e-15);
  }
}

TEST(PolychromaticMaterial, TransmissionIsOneAtZeroAndDecreasing) {
  const PolychromaticMaterial al(BeamModel{}, kAluminium);
  EXPECT_EQ(al.transmission(0.0), 1.0);
  double previous = 1.0;
  for (int i = 1; i <= 6000; ++i) {
    const double t = al.transmission(0.01 * i);
    ASSERT_LT(t, previous) << "x = " << 0.01 * i;
    ASSERT_GT(t, 0.0);
    previous = t;
  }
}

TEST(PolychromaticMaterial, TwentyMillimetresOfAluminiumAt220kV) {
  BeamModel beam;
  beam.tube_kv = 220.0;
  beam.filters = {{"Be", 1.848, 1.0}, {"Al", 2.699, 1.0}};
  beam.detector_window = {"Al", 2.699, 0.5};
  beam.scintillator = {"CsI", 4.51, 0.6};
  const PolychromaticMaterial al(beam, kAluminium);
  const double t20 = al.transmission(20.0);
  std::printf(
      "T(20 mm Al, 220 kV) = %.4f (thesis: about 0.2); mu_eff(0) = %.4f/mm, "
      "mu_eff(20) = %.4f/mm; mean energy %.1f keV\n",
      t20, al.effectiveMuPerMm(0.0), al.effectiveMuPerMm(20.0), beam.spectrum().meanEnergyKev());
  EXPECT_GT(t20, 0.12);
  EXPECT_LT(t20, 0.30);
}

TEST(PolychromaticMaterial, DerivativeMatchesFiniteDifferences) {
  const PolychromaticMaterial al(BeamModel{}, kAluminium);
  for (double x : {0.5, 5.0, 20.0, 55.0}) {
    const double h = 1e-5;
    const double fd = (al.transmission(x + h) - al.transmission(x - h)) / (2 * h);
    EXPECT_NEAR(al.derivative(x), fd, 1e-9) << "x = " << x;
    EXPECT_NEAR(al.effectiveMuPerMm(x), -al.derivative(x) / al.transmission(x), 1e-12);
  }
}

TEST(PolychromaticMaterial, TableMatchesDirectEvaluation) {
  // The thesis beam, and a 40 kV beam behind only 0.5 mm Be: a much larger
  // spread of mu, so a finer table step.
  BeamModel soft;
  soft.tube_kv = 40.0;
  soft.filters = {{"Be", 1.848, 0.5}};
  for (const BeamModel& beam : {BeamModel{}, soft}) {
    const PolychromaticMaterial al(beam, kAluminium);
    const TransmissionTable table = al.table(60.0);
    double worst = 0.0;
    for (int i = 0; i <= 600000; ++i) {
      const double x = 1e-4 * i;
      worst = std::max(worst, std::abs(table(x) - al.transmission(x)));
    }
    std::printf("%g kV: table step %.4g mm, worst error %.3g\n", beam.tube_kv, table.stepMm(),
                worst);
    EXPECT_LT(worst, 1e-8);
    EXPECT_EQ(table(0.0), 1.0);
  }
  const TransmissionTable free = polychromaticTransmission(BeamModel{}, kAluminium, 30.0);
  EXPECT_DOUBLE_EQ(free.maxPathMm(), 30.0);
}

TEST(PolychromaticMaterial, BeamHardening) {
  const PolychromaticMaterial al(BeamModel{}, kAluminium);
  double previous = al.effectiveMuPerMm(0.0);
  for (int i = 1; i <= 600; ++i) {
    const double mu = al.effectiveMuPerMm(0.1 * i);
    ASSERT_LT(mu, previous) << "x = " << 0.1 * i;
    previous = mu;
  }
  // Still finite far beyond any underflow of T itself.
  EXPECT_TRUE(std::isfinite(al.effectiveMuPerMm(1e5)));
  EXPECT_GT(al.effectiveMuPerMm(1e5), 0.0);
}

// --- JSON -------------------------------------------------------------------

constexpr const char* kBeamJson = R"({
  "tube_kv": 220,
  "filters": [{"compound": "Be", "density_g_cm3": 1.848, "thickness_mm": 1},
              {"compound": "Al", "density_g_cm3": 2.699, "thickness_mm": 1}],
  "detector_window": {"compound": "Al", "density_g_cm3": 2.699, "thickness_mm": 0.5},
  "scintillator": {"compound": "CsI", "density_g_cm3": 4.51, "thickness_mm": 0.6}
})";

TEST(BeamModel, JsonRoundTrip) {
  const ConfigNode root = ConfigNode::parse(kBeamJson, "beam.json");
  const BeamModel beam = BeamModel::fromConfig(root);
  EXPECT_NO_THROW(root.finish());
  EXPECT_EQ(beam.tube_kv, 220.0);
  EXPECT_EQ(beam.bin_kev, 0.5);
  ASSERT_EQ(beam.filters.size(), 2u);
  EXPECT_EQ(beam.filters[0].compound, "Be");
  const BeamModel again = BeamModel::fromConfig(ConfigNode::fromJson(beam.toJson(), "again"));
  EXPECT_EQ(again.toJson(), beam.toJson());
  EXPECT_EQ(again.detectorWeights(), beam.detectorWeights());
  // NIST names work as compounds.
  const Layer water = Layer::fromConfig(ConfigNode::parse(
      R"({"compound": "Water, Liquid", "density_g_cm3": 1, "thickness_mm": 2})", "w.json"));
  EXPECT_GT(water.muPerMm(50.0), 0.0);
}

// Applies `edit` to the reference beam JSON and expects an Error at `key`.
void expectErrorAt(const std::function<void(nlohmann::json&)>& edit, const std::string& key) {
  nlohmann::json doc = nlohmann::json::parse(kBeamJson);
  edit(doc);
  try {
    BeamModel::fromConfig(ConfigNode::fromJson(doc, "beam.json"));
    ADD_FAILURE() << "no error for " << key;
  } catch (const Error& e) {
    EXPECT_EQ(e.where().file, "beam.json");
    EXPECT_EQ(e.where().key_path, key) << e.what();
  }
}

TEST(BeamModel, BadJsonNamesTheKey) {
  expectErrorAt([](auto& d) { d["filters"][1]["compound"] = "Xq"; }, "/filters/1/compound");
  expectErrorAt([](auto& d) { d["detector_window"]["thickness_mm"] = -0.5; },
                "/detector_window/thickness_mm");
  expectErrorAt([](auto& d) { d["filters"][0]["density_g_cm3"] = 0; }, "/filters/0/density_g_cm3");
  expectErrorAt([](auto& d) { d["tube_kv"] = 10; }, "/tube_kv");
  expectErrorAt([](auto& d) { d["tube_kv"] = 500; }, "/tube_kv");
  expectErrorAt([](auto& d) { d["bin_kev"] = 0; }, "/bin_kev");
  expectErrorAt([](auto& d) { d["scintillator"]["thickness_mm"] = 0; },
                "/scintillator/thickness_mm");
  expectErrorAt([](auto& d) { d["filters"] = "Al"; }, "/filters");
  expectErrorAt([](auto& d) { d.erase("detector_window"); }, "/");
  // A misspelled key is reported by finish().
  const ConfigNode root = ConfigNode::parse(
      R"({"tube_kv": 100, "filters": [], "detector_window": {"compound": "C", "density_g_cm3": 1.7,
          "thickness_mm": 1}, "scintilator": {}})",
      "beam.json");
  BeamModel::fromConfig(root);
  EXPECT_THROW(root.finish(), Error);
}

TEST(Layer, ValidateRejectsBadValues) {
  EXPECT_NO_THROW((Layer{"CsI", 4.51, 0.6}.validate()));
  EXPECT_THROW((Layer{"Qz", 1.0, 1.0}.validate()), Error);
  EXPECT_THROW((Layer{"Al", -2.7, 1.0}.validate()), Error);
  EXPECT_THROW((Layer{"Al", 2.7, -1.0}.validate()), Error);
  EXPECT_THROW((Layer{"Al", 2.7, NAN}.validate()), Error);
  BeamModel beam;
  beam.tube_kv = 500.0;
  EXPECT_THROW(beam.validate(), Error);
}

}  // namespace
}  // namespace xgauge
