// The characterisation job, its steps and its files (characterize.h).
#include "xgauge/characterize/characterize.h"

#include "xgauge/core/error.h"
#include "xgauge/image/bad_pixels.h"
#include "xgauge/image/radiograph_file.h"
#include "xgauge/version.h"
#include "xgauge/xray/machine.h"

#include <fnmatch.h>
#include <spdlog/spdlog.h>

#include <algorithm>

namespace xgauge {

namespace fs = std::filesystem;

namespace {

// A file name with '*' names the sorted matches in its folder.
std::vector<fs::path> expand(const fs::path& pattern, const ConfigNode& where) {
  const std::string name = pattern.filename().string();
  if (name.find('*') == std::string::npos) return {pattern};
  std::vector<fs::path> out;
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(pattern.parent_path(), error))
    if (fnmatch(name.c_str(), entry.path().filename().c_str(), 0) == 0) out.push_back(entry.path());
  if (out.empty()) where.fail("no file matches " + pattern.string());
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<fs::path> fileList(const ConfigNode& node, const fs::path& folder) {
  std::vector<fs::path> out;
  if (node.isString()) return expand(folder / node.string(), node);
  if (!node.isArray() || node.size() == 0)
    node.fail("expected a file name or a non-empty list of them");
  for (size_t i = 0; i < node.size(); ++i)
    for (const fs::path& p : expand(folder / node[i].string(), node[i])) out.push_back(p);
  return out;
}

Image readInput(const fs::path& file, const Machine& machine, Characterization& c) {
  std::string sha;
  const ExpectedImageSize size{machine.columns, machine.rows, "the machine's detector"};
  RadiographFile read = readRadiograph(file, &sha, &size);
  c.inputs.push_back({file.string(), sha});
  return std::move(read.image);
}

Image meanOf(const std::vector<Image>& frames) {
  Image out(frames.front().width(), frames.front().height(), 0.0f);
  for (const Image& f : frames)
    for (size_t i = 0; i < out.size(); ++i) out.pixels()[i] += f.pixels()[i];
  for (float& v : out.pixels()) v /= static_cast<float>(frames.size());
  return out;
}

// (raw - dark) / (flat - dark), bad pixels repaired from their neighbours.
Image corrected(const Image& raw, const Image& dark, const Image& flat,
                const ImageT<uint8_t>& bad) {
  Image out(raw.width(), raw.height());
  for (size_t i = 0; i < out.size(); ++i) {
    const float d = flat.pixels()[i] - dark.pixels()[i];
    out.pixels()[i] =
        bad.pixels()[i] || !(d > 0.0f) ? 0.0f : (raw.pixels()[i] - dark.pixels()[i]) / d;
  }
  ImageT<uint8_t> mask = bad;
  for (size_t i = 0; i < out.size(); ++i)
    if (!(flat.pixels()[i] - dark.pixels()[i] > 0.0f)) mask.pixels()[i] = 1;
  repairBadPixels(out, mask);
  return out;
}

nlohmann::json estimateJson(const Estimate& e) {
  return {{"value", e.value}, {"uncertainty", e.uncertainty}};
}

}  // namespace

CharacterizeJob CharacterizeJob::load(const fs::path& path) {
  const ConfigNode root = ConfigNode::loadFile(path);
  const fs::path folder = path.parent_path();
  CharacterizeJob job;
  job.machine_file = folder / root.get<std::string>("machine");
  job.darks = fileList(root.at("darks"), folder);
  job.flats = fileList(root.at("flats"), folder);
  if (auto shots = root.find("shots")) {
    auto one = [&](const char* key) -> std::optional<fs::path> {
      if (auto n = shots->find(key)) return folder / n->string();
      return std::nullopt;
    };
    job.edge = one("edge"), job.crosstalk = one("crosstalk");
    if (auto lag = shots->find("lag")) {
      job.lag_bright = folder / lag->get<std::string>("bright");
      job.lag_dark = folder / lag->get<std::string>("after");
    }
  }
  if (auto f = root.find("max_sigma_fraction")) job.max_sigma_fraction = f->number(0.05, 2.0);
  root.find("description");  // free text
  root.finish();
  return job;
}

int characterizeSteps(const CharacterizeJob& job) {
  return 1 + (job.crosstalk ? 1 : 0) + (job.lag_bright ? 1 : 0) + (job.edge ? 1 : 0);
}

Characterization characterize(const CharacterizeJob& job, const std::function<void()>& advance) {
  Characterization out;
  const Machine machine = Machine::load(job.machine_file);
  std::vector<Image> darks, flats;
  for (const fs::path& f : job.darks) darks.push_back(readInput(f, machine, out));
  for (const fs::path& f : job.flats) flats.push_back(readInput(f, machine, out));
  const Image dark = meanOf(darks), flat = meanOf(flats);
  out.bad_pixels = findDetectorBadPixels(darks, dark, flat);
  const ImageT<uint8_t> bad = out.bad_pixels.mask();
  out.steps.push_back(
      fmt::format("bad pixels from {} darks and {} flats: {} dead, {} hot, {} noisy", darks.size(),
                  flats.size(), out.bad_pixels.dead, out.bad_pixels.hot, out.bad_pixels.noisy));
  advance();
  if (job.crosstalk) {
    out.crosstalk =
        estimateCrosstalk(corrected(readInput(*job.crosstalk, machine, out), dark, flat, bad));
    advance();
  }
  if (job.lag_bright) {
    const Image bright = readInput(*job.lag_bright, machine, out);
    out.lag = estimateLag(bright, readInput(*job.lag_dark, machine, out), dark, bad);
    advance();
  }
  if (job.edge) {
    EdgeHaloOptions options;
    options.crosstalk = out.crosstalk ? out.crosstalk->value : 0.0;
    options.max_sigma_fraction = job.max_sigma_fraction;
    options.field = OpenBeamField::fromFrames(machine.openBeamGeometry(), &dark, &flat);
    out.halo = fitEdgeHalo(corrected(readInput(*job.edge, machine, out), dark, flat, bad),
                           machine.pitch_u_mm, options);
    advance();
  }
  return out;
}

nlohmann::json badPixelsJson(const BadPixelMap& map) {
  nlohmann::json dead = nlohmann::json::array(), hot = nlohmann::json::array(),
                 noisy = nlohmann::json::array();
  for (int y = 0; y < map.kinds.height(); ++y)
    for (int x = 0; x < map.kinds.width(); ++x) {
      const uint8_t k = map.kinds(x, y);
      if (k & kDeadPixel) dead.push_back({x, y});
      if (k & kHotPixel) hot.push_back({x, y});
      if (k & kNoisyPixel) noisy.push_back({x, y});
    }
  return {{"columns", map.kinds.width()},
          {"rows", map.kinds.height()},
          {"dead", dead},
          {"hot", hot},
          {"noisy", noisy}};
}

nlohmann::json detectorJson(const Characterization& c, const std::string& bad_pixels_file) {
  nlohmann::json out = {{"software", "xgauge " XGAUGE_VERSION_STRING}};
  if (c.halo) {
    const EdgeHaloFit& h = *c.halo;
    nlohmann::json candidates = nlohmann::json::array();
    for (const EdgeHaloCandidate& k : h.candidates) {
      nlohmann::json model = k.scatter.toJson();
      model["shape"] = toString(k.scatter.shape), model["border"] = toString(k.scatter.border);
      candidates.push_back({{"scatter", model},
                            {"misfit_ratio", k.misfit_ratio},
                            {"residual_correlation", k.residual_correlation},
                            {"bic", k.bic},
                            {"parameters", k.parameters}});
    }
    nlohmann::json scatter = h.scatter.toJson();
    scatter["shape"] = toString(h.scatter.shape), scatter["border"] = toString(h.scatter.border);
    out["halo"] = {
        {"scatter", scatter},
        {"gaussian_equivalent_sigma_mm", h.equivalent_sigma_mm},
        {"gaussian_equivalent_sigma_uncertainty_mm", h.equivalent_sigma_uncertainty_mm},
        {"noise_scale", h.noise_scale},
        {"split_halves",
         {{"halves", {"upper", "lower", "left", "right"}},
          {"weight", h.split_halves_weight},
          {"gaussian_equivalent_sigma_mm", h.split_halves_equivalent_sigma_mm},
          {"weight_term", h.split_halves_weight_term},
          {"gaussian_equivalent_sigma_term_mm", h.split_halves_equivalent_sigma_term_mm}}},
        {"open_beam_heel",
         {{"weight_change", h.heel_share_weight_change},
          {"gaussian_equivalent_sigma_change_mm", h.heel_share_equivalent_sigma_change_mm}}},
        {"kernel_choice",
         {{"shape", h.kernel_choice_shape.empty() ? nlohmann::json()
                                                  : nlohmann::json(h.kernel_choice_shape)},
          {"weight_change", h.kernel_choice_weight_change},
          {"gaussian_equivalent_sigma_change_mm", h.kernel_choice_equivalent_sigma_change_mm}}},
        {"binning", h.binning},
        {"bins", h.bins},
        {"candidates", candidates},
        {"choice", h.choice}};
  }
  if (c.lag) out["lag_fraction"] = estimateJson(*c.lag);
  if (c.crosstalk) out["crosstalk"] = estimateJson(*c.crosstalk);
  out["bad_pixels"] = {{"file", bad_pixels_file},
                       {"dead", c.bad_pixels.dead},
                       {"hot", c.bad_pixels.hot},
                       {"noisy", c.bad_pixels.noisy}};
  nlohmann::json inputs = nlohmann::json::array();
  for (const InputFile& f : c.inputs) inputs.push_back({{"file", f.file}, {"sha256", f.sha256}});
  out["inputs"] = inputs;
  return out;
}

std::string characterizationReport(const Characterization& c) {
  std::string text;
  for (const std::string& s : c.steps) text += s + "\n";
  if (c.crosstalk)
    text += fmt::format("crosstalk: c = {:.5f} +- {:.5f}\n", c.crosstalk->value,
                        c.crosstalk->uncertainty);
  if (c.lag) text += fmt::format("lag: g = {:.6f} +- {:.2g}\n", c.lag->value, c.lag->uncertainty);
  if (c.halo) {
    const EdgeHaloFit& h = *c.halo;
    const ScatterModel& m = h.scatter;
    text += fmt::format(
        "halo: {} kernel, {} border, weight {:.4f} +- {:.2g}, sigma {:.2f} +- {:.2g} mm",
        toString(m.shape), toString(m.border), m.weight, m.weight_uncertainty, m.sigma_mm,
        m.sigma_uncertainty_mm);
    if (m.shape == HaloShape::kGaussExp)
      text +=
          fmt::format(", tail {:.3f} +- {:.3f} of length {:.2f} +- {:.2f} mm", m.tail_fraction,
                      m.tail_fraction_uncertainty, m.tail_length_mm, m.tail_length_uncertainty_mm);
    if (m.shape == HaloShape::kTwoGauss)
      text += fmt::format(", second sigma {:.2f} +- {:.2f} mm with {:.3f} +- {:.3f}", m.sigma2_mm,
                          m.sigma2_uncertainty_mm, m.fraction2, m.fraction2_uncertainty);
    text += fmt::format("; Gaussian-equivalent sigma {:.2f} +- {:.2f} mm\n", h.equivalent_sigma_mm,
                        h.equivalent_sigma_uncertainty_mm);
    if (m.equivalent_end) {
      const ScatterModel end = m.as(*m.equivalent_end);
      text += fmt::format(
          "  the budget's kernel at the equivalent width's end (u {:.2f} mm without the kernel "
          "choice): weight {:.4f}, sigma_eq {:.2f} mm\n",
          m.equivalent_end->equivalent_sigma_uncertainty_mm, end.weight, end.equivalentSigmaMm());
    }
    if (m.kernel_choice)
      text += fmt::format("  the budget's other kernel: {}, weight {:.4f}, sigma_eq {:.2f} mm\n",
                          toString(m.kernel_choice->shape), m.kernel_choice->weight,
                          m.as(*m.kernel_choice).equivalentSigmaMm());
    for (const EdgeHaloCandidate& k : h.candidates)
      text += fmt::format(
          "  {:9} {:6}  misfit {:.3f} (correlation {:.1f})  BIC {:+.1f}  weight {:.4f}  sigma_eq "
          "{:.2f} mm\n",
          toString(k.scatter.shape), toString(k.scatter.border), k.misfit_ratio,
          k.residual_correlation, k.bic - h.candidates.front().bic, k.scatter.weight,
          k.scatter.equivalentSigmaMm());
    text += "  chosen: " + h.choice + "\n";
  }
  return text;
}

}  // namespace xgauge
