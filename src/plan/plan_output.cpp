// The plan's outputs (docs/formats.md, "xgauge plan"): plan.json, the best
// set's measurement job and report.html, a static page (tables, one SVG
// chart per dimension, each view's simulated radiograph).
#include "views.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/output.h"
#include "xgauge/report/html.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>

namespace xgauge {

namespace {

nlohmann::json finite(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json setJson(const PlanJob& job, const PlanResult& result, const PredictedSet& set) {
  nlohmann::json beyond = nlohmann::json::object();
  for (const auto& [view, mm] : set.beyond_range) beyond[view] = mm;
  nlohmann::json views = nlohmann::json::array();
  for (int v : set.views) views.push_back(job.views[static_cast<size_t>(v)].name);
  nlohmann::json dims = nlohmann::json::object();
  for (const PredictedDimension& d : set.dimensions) {
    nlohmann::json e = {{"expanded_uncertainty", d.identifiable ? finite(d.expanded) : nullptr},
                        {"identifiable", d.identifiable}};
    if (d.tolerance_width) {
      e["tolerance_width"] = *d.tolerance_width;
      e["u_over_t"] = finite(*d.u_over_t());
    }
    dims[d.name] = std::move(e);
  }
  for (const PredictedDimension& d : set.screened)
    if (dims.contains(d.name))
      dims[d.name]["screened_expanded_uncertainty"] = d.identifiable ? finite(d.expanded) : nullptr;
  nlohmann::json out = {{"views", views},
                        {"patterns", set.patterns},
                        {"score", finite(set.score)},
                        {"predicted_by", set.budgeted ? "budget" : "screening"},
                        {"scale_from", set.scale_from_curve() ? "curve" : "known move"},
                        {"beyond_calibrated_range", beyond},
                        {"dimensions", dims}};
  if (set.budget) {
    nlohmann::json components = nlohmann::json::object();
    for (const DimensionUncertainty& d : set.budget->dimensions) {
      nlohmann::json list = nlohmann::json::array();
      for (const UncertaintyComponent& c : d.components)
        list.push_back({{"name", c.name}, {"contribution", c.contribution}});
      components[d.name] = std::move(list);
    }
    out["components"] = std::move(components);
    out["notes"] = set.budget->notes;
    out["complete"] = set.complete();
    out["unpropagated"] = set.budget->unpropagated;
    out["job"] = measurementJobFor(job, result, set.views);
  }
  return out;
}

std::string criterionName(const PlanJob& job) {
  switch (job.criterion) {
    case PlanCriterion::kWorst:
      return "the largest U/T over the toleranced dimensions";
    case PlanCriterion::kSum:
      return "the sum of U/T over the toleranced dimensions";
    case PlanCriterion::kDimension:
      return "the U of " + job.criterion_dimension;
  }
  return {};
}

nlohmann::json planJson(const PlanJob& job, const PlanResult& result) {
  nlohmann::json views = nlohmann::json::array();
  for (const CandidateView& v : job.views) {
    const Vec3 c = v.pose.translation_mm;
    views.push_back({{"name", v.name},
                     {"rotation_deg", {v.rotation_deg[0], v.rotation_deg[1], v.rotation_deg[2]}},
                     {"stage_mm", v.stage_mm},
                     {"turntable_deg", v.turntable_deg},
                     {"pose", {{"rotation_deg", {v.pose.eulerDeg()[0], v.pose.eulerDeg()[1], v.pose.eulerDeg()[2]}},
                               {"translation_mm", {c[0], c[1], c[2]}}}}});
  }
  nlohmann::json ranked = nlohmann::json::array(), compared = nlohmann::json::array();
  constexpr size_t kListed = 500;  // sets listed in plan.json, best first
  for (size_t k = 0; k < result.ranked.size() && k < kListed; ++k)
    ranked.push_back(setJson(job, result, result.ranked[k]));
  for (const PredictedSet& s : result.compared) compared.push_back(setJson(job, result, s));
  return {{"plan", job.file.string()},
          {"criterion", criterionName(job)},
          {"radiographs", job.per_set},
          {"open_beam_noise", job.open_beam_noise},
          {"search", result.search},
          {"screened", result.screened},
          {"seconds", result.seconds},
          {"views", views},
          {"ranked", ranked},
          {"compared", compared}};
}

std::string number(double v) { return std::isfinite(v) ? fmt::format("{:.4f}", v) : "not determined"; }

std::string setRow(const PlanJob& job, const PredictedSet& set, const std::string& label) {
  std::string views;
  for (size_t k = 0; k < set.views.size(); ++k)
    views += fmt::format("{}{} ({})", k ? ", " : "", job.views[static_cast<size_t>(set.views[k])].name,
                         set.patterns[k]);
  std::string by =
      !set.budgeted   ? "screening"
      : set.complete() ? "budget"
                       : "budget without " + fmt::format("{}", fmt::join(set.budget->unpropagated, ", ")) +
                            " (U too small)";
  for (const auto& [view, mm] : set.beyond_range)
    by += fmt::format("; {} has paths to {:.1f} mm, beyond the calibrated range", view, mm);
  std::string row = fmt::format("<tr><td>{}</td><td style='text-align:left'>{}</td><td>{}</td><td>{}</td>",
                                escapeHtml(label), escapeHtml(views), number(set.score),
                                escapeHtml(by));
  for (const PredictedDimension& d : set.dimensions)
    row += fmt::format("<td>{}{}</td>", d.identifiable ? fmt::format("{:.4f}", d.expanded) : "—",
                       d.u_over_t() && std::isfinite(*d.u_over_t())
                           ? fmt::format(" <small>({:.2f} T)</small>", *d.u_over_t())
                           : "");
  return row + "</tr>\n";
}

// One chart per dimension: its predicted U (or U/T) over every screened
// set, the sets in the ranking's order; the budgeted ones marked.
std::string chartOf(const PlanResult& result, size_t d) {
  constexpr int kWidth = 520, kHeight = 140, kPad = 30;
  double top = 0.0;
  for (const PredictedSet& s : result.ranked)
    if (s.dimensions[d].identifiable) top = std::max(top, s.dimensions[d].expanded);
  if (!(top > 0.0)) top = 1.0;
  const size_t n = result.ranked.size();
  std::string dots;
  for (size_t k = 0; k < n; ++k) {
    const PredictedSet& s = result.ranked[k];
    const double x = kPad + (kWidth - 2.0 * kPad) * (n > 1 ? static_cast<double>(k) / static_cast<double>(n - 1) : 0.5);
    if (!s.dimensions[d].identifiable) {
      dots += fmt::format("<text x='{:.1f}' y='{}' font-size='9' fill='#b00'>×</text>", x - 3, kPad - 4);
      continue;
    }
    const double y = kHeight - kPad - (kHeight - 2.0 * kPad) * s.dimensions[d].expanded / top;
    dots += fmt::format("<circle cx='{:.1f}' cy='{:.1f}' r='{}' fill='{}'/>", x, y,
                        s.budgeted ? 3 : 1.5, s.budgeted ? "#d62728" : "#1f77b4");
  }
  return fmt::format(
      "<svg width='{0}' height='{1}' role='img'><rect x='{2}' y='{2}' width='{3}' height='{4}' "
      "fill='none' stroke='#ccc'/><text x='2' y='{5}' font-size='10'>{6:.4f}</text>"
      "<text x='2' y='{7}' font-size='10'>0</text><text x='{2}' y='{8}' font-size='10'>sets, "
      "best first (red: the measurement's budget; blue: screened; ×: not determined)</text>{9}</svg>",
      kWidth, kHeight + 14, kPad, kWidth - 2 * kPad, kHeight - 2 * kPad, kPad + 4, top,
      kHeight - kPad, kHeight + 10, dots);
}

std::string reportHtml(const PlanJob& job, const PlanResult& result) {
  std::string body = fmt::format("<h1>View plan: {}</h1><p>{}</p><p>Ranked by {}; {}. {} candidate views, "
                                 "{} radiographs per set, open-beam noise {}. {:.1f} s.</p>",
                                 escapeHtml(job.file.filename().string()), escapeHtml(job.description),
                                 escapeHtml(criterionName(job)), escapeHtml(result.search),
                                 job.views.size(), job.per_set, job.open_beam_noise, result.seconds);
  std::string head = "<tr><th></th><th>views</th><th>criterion</th><th>predicted by</th>";
  const std::vector<PredictedDimension>& dims = result.ranked.front().dimensions;
  for (const PredictedDimension& d : dims) head += "<th>U " + escapeHtml(d.name) + "</th>";
  head += "</tr>\n";
  body += "<h2>The best sets</h2><table>" + head;
  for (size_t k = 0; k < result.ranked.size() && k < 10; ++k)
    body += setRow(job, result.ranked[k], fmt::format("#{}", k + 1));
  for (const PredictedSet& s : result.compared) body += setRow(job, s, "compared");
  body += "</table><h2>Each dimension's U over the candidate sets</h2><div class='charts'>";
  for (size_t d = 0; d < dims.size(); ++d)
    body += fmt::format("<figure>{}<figcaption>{}</figcaption></figure>", chartOf(result, d),
                        escapeHtml(dims[d].name));
  body += "</div><h2>The views, simulated at the nominal part</h2><div class='views'>";
  for (size_t v = 0; v < job.views.size(); ++v) {
    const CandidateView& view = job.views[v];
    const Image& image = result.view_images[v];
    const nlohmann::json picture = greyPicture(image, image.rect(), GreyWindow{0.0, 1.0}, 240);
    body += fmt::format(
        "<figure><img src='{}' width='240' height='240' alt='{}'><figcaption>{}: rotation [{}, {}, "
        "{}] deg, stage {} mm, turntable {} deg</figcaption></figure>",
        picture.at("uri").get<std::string>(), view.name, view.name, view.rotation_deg[0],
        view.rotation_deg[1], view.rotation_deg[2], view.stage_mm, view.turntable_deg);
  }
  body += "</div>";
  return fmt::format(
      "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><meta "
      "http-equiv='Content-Security-Policy' content=\"default-src 'none'; img-src data:; style-src "
      "'unsafe-inline'\"><title>xgauge view plan</title><style>body{{font:14px/1.45 \"DejaVu "
      "Sans\",sans-serif;margin:24px;color:#222;max-width:1500px}}table{{border-collapse:collapse}}"
      "td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right;font-variant-numeric:tabular-"
      "nums}}th{{background:#f3f3f3}}.views,.charts{{display:flex;flex-wrap:wrap;gap:12px}}figure{{"
      "margin:0}}figcaption{{color:#555;font-size:12px;max-width:520px}}</style></head><body>{}"
      "</body></html>\n",
      body);
}

}  // namespace

nlohmann::json measurementJobFor(const PlanJob& job, const PlanResult& result,
                                 const std::vector<int>& views) {
  std::vector<PixelRect> white;
  for (int v : views) white.push_back(result.white_regions[static_cast<size_t>(v)]);
  return plan_internal::measurementJobFrom(job, views, white);
}

void writePlan(const PlanJob& job, const PlanResult& result, const std::filesystem::path& folder) {
  const nlohmann::json plan = planJson(job, result);
  nlohmann::json measurement = measurementJobFor(job, result, result.ranked.front().views);
  measurement["description"] = fmt::format(
      "The measurement job of the best set of {} (xgauge plan): name each view's radiograph "
      "(and its dark and flat frames) in place of <view>.tif",
      job.file.filename().string());
  const std::string page = reportHtml(job, result);
  OutputTransaction outputs;
  createOutputFolder(folder);
  writeFileAtomically(folder / "plan.json", plan.dump(2) + "\n");
  writeFileAtomically(folder / "job.json", measurement.dump(2) + "\n");
  writeFileAtomically(folder / "report.html", page);
  outputs.commit();
}

}  // namespace xgauge
