#include "xgauge/report/part_page.h"

#include "xgauge/report/html.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>

namespace xgauge {
namespace {

// A label needs this many visible pixels of its face to be drawn.
constexpr int kLabelPixels = 40;


Rgb hueOf(const std::string& type) {
  if (type == "plane") return {158, 202, 225};
  if (type == "cylinder") return {253, 174, 107};
  if (type == "cone") return {161, 217, 155};
  if (type == "sphere") return {188, 189, 220};
  if (type == "torus") return {242, 224, 109};
  return {200, 200, 200};  // freeform
}

std::string css(const Rgb& c) { return fmt::format("rgb({},{},{})", c[0], c[1], c[2]); }

constexpr const char* kStyle = R"(
body{font:14px/1.45 "DejaVu Sans",sans-serif;margin:24px;color:#222;max-width:1500px}
h1{font-size:20px}h2{font-size:16px;margin-top:28px}
.views{display:flex;flex-wrap:wrap;gap:16px}
figure{margin:0}figcaption{text-align:center;color:#555}
.picture{position:relative;display:inline-block;border:1px solid #ccc}
.picture img{display:block;width:480px;height:480px;image-rendering:auto}
.label{position:absolute;transform:translate(-50%,-50%);font-size:11px;font-weight:bold;
 background:rgba(255,255,255,.8);border-radius:3px;padding:0 2px;pointer-events:none}
table{border-collapse:collapse;margin-top:8px}td,th{border:1px solid #ccc;padding:2px 6px;
 text-align:right;font-variant-numeric:tabular-nums}th{background:#f3f3f3}
td.l,th.l{text-align:left}.swatch{display:inline-block;width:12px;height:12px;border:1px solid #888;
 vertical-align:middle;margin:0 4px 0 12px}
)";

std::string page(const std::string& title, const std::string& body) {
  return fmt::format(R"(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="default-src 'none'; img-src data:; style-src 'unsafe-inline'">
<title>{0}</title><style>{1}</style></head>
<body><h1>{0}</h1>
{2}
<p>Written by xgauge on {3}.</p>
</body></html>
)",
                     escapeHtml(title), kStyle, body, utcTimestamp());
}

// One picture with its labels; `label` names a region (empty: none).
std::string figure(const PartPicture& picture,
                   const std::function<std::string(int)>& label) {
  std::string labels;
  for (const PartPicture::Label& l : picture.labels) {
    if (l.pixels < kLabelPixels) continue;
    const std::string text = label(l.region);
    if (text.empty()) continue;
    labels += fmt::format(R"(<span class="label" style="left:{:.2f}%;top:{:.2f}%">{}</span>)",
                          100.0 * (l.x + 0.5) / picture.width,
                          100.0 * (l.y + 0.5) / picture.height, escapeHtml(text));
  }
  return fmt::format(
      R"(<figure><div class="picture"><img alt="{0}" src="{1}">{2}</div><figcaption>from the {0}</figcaption></figure>)",
      escapeHtml(picture.view), pngDataUri(encodePicture(picture)), labels);
}

std::string number(double value) { return fmt::format("{:.4f}", value); }
std::string point(const Vec3& p) {
  return fmt::format("({:.3f}, {:.3f}, {:.3f})", p.x(), p.y(), p.z());
}

}  // namespace

std::string entityName(const StepFace& face) {
  return face.entity > 0 ? fmt::format("#{}", face.entity) : std::string();
}

Rgb faceColour(const StepFace& face) {
  const Rgb hue = hueOf(face.surface_type);
  // Five shades, by face number: neighbours of one type seldom share one.
  const double shade = 0.82 + 0.09 * ((face.index * 3) % 5) / 2.0;
  Rgb out;
  for (int k = 0; k < 3; ++k)
    out[k] = static_cast<uint8_t>(std::clamp(std::lround(hue[k] * shade), 0L, 255L));
  return out;
}

nlohmann::json faceJson(const StepFace& face) {
  const auto vec = [](const Vec3& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); };
  nlohmann::json out = {{"face", face.index},
                        {"entity", face.entity},
                        {"name", face.name},
                        {"type", face.surface_type},
                        {"area_mm2", face.area_mm2},
                        {"centroid_mm", vec(face.centroid_mm)}};
  const Surface& s = face.surface;
  switch (s.kind) {
    case SurfaceKind::kPlane:
      out["normal"] = vec(face.outward * s.axis);
      break;
    case SurfaceKind::kCylinder:
    case SurfaceKind::kCone:
    case SurfaceKind::kTorus:
      out["axis"] = vec(s.axis);
      out["origin_mm"] = vec(s.origin);
      out["radius_mm"] = s.radius;
      if (s.kind == SurfaceKind::kCone) out["semi_angle_deg"] = s.semi_angle * 180.0 / std::numbers::pi;
      if (s.kind == SurfaceKind::kTorus) out["minor_radius_mm"] = s.minor_radius;
      out["outward"] = face.outward > 0 ? "away from the axis" : "towards the axis";
      break;
    case SurfaceKind::kSphere:
      out["centre_mm"] = vec(s.origin);
      out["radius_mm"] = s.radius;
      break;
    case SurfaceKind::kOther:
      out["mean_normal"] = vec(face.normal);
      break;
  }
  return out;
}

std::string facesPage(const std::string& title, const StepSolid& solid,
                      const std::vector<PartPicture>& pictures) {
  std::string body = fmt::format(
      "<p>{} faces. A dimension names its faces by a point on them (<code>{{\"at\": [x, y, "
      "z]}}</code>, in this file's frame, mm), by their STEP entity (<code>\"#42\"</code>), "
      "their name, or the number drawn here (docs/your-part.md).</p><p>",
      solid.faces.size());
  for (const char* type : {"plane", "cylinder", "cone", "sphere", "torus", "freeform"})
    body += fmt::format(R"(<span class="swatch" style="background:{}"></span>{})",
                        css(hueOf(type)), type);
  body += "</p><div class=\"views\">";
  for (const PartPicture& picture : pictures)
    body += figure(picture, [](int region) { return std::to_string(region + 1); });
  body += "</div><h2>Faces</h2><table><tr><th>face</th><th>entity</th><th class=l>name</th>"
          "<th class=l>type</th><th>area mm²</th><th class=l>centroid mm</th>"
          "<th class=l>normal or axis</th><th>radius mm</th></tr>";
  for (const StepFace& face : solid.faces) {
    const Surface& s = face.surface;
    const std::string direction =
        s.kind == SurfaceKind::kPlane ? point(face.outward * s.axis)
        : s.kind == SurfaceKind::kOther || s.kind == SurfaceKind::kSphere
            ? std::string()
            : fmt::format("{} through {}", point(s.axis), point(s.origin));
    const std::string radius =
        s.kind == SurfaceKind::kPlane || s.kind == SurfaceKind::kOther ? "" : number(s.radius);
    body += fmt::format(
        "<tr><td>{}</td><td>{}</td><td class=l>{}</td><td class=l>{}</td><td>{:.3f}</td>"
        "<td class=l>{}</td><td class=l>{}</td><td>{}</td></tr>",
        face.index, entityName(face), escapeHtml(face.name),
        escapeHtml(face.surface_type), face.area_mm2, point(face.centroid_mm), direction, radius);
  }
  body += "</table>";
  return page(title, body);
}

std::string checkPage(const std::string& title,
                      const std::vector<DimensionCheckSection>& sections) {
  std::string body = fmt::format(
      "<p>{} dimensions, each moved by its step either side of nominal with the others at "
      "nominal. In the pictures the faces a dimension moves are red, the faces it stretches "
      "orange; the part's outline at nominal &minus; step is blue, at nominal + step red. The "
      "buildable range is where the part's constraints hold and no face turns over.</p>",
      sections.size());
  body += "<table><tr><th class=l>dimension</th><th>nominal</th><th>step</th>"
          "<th>buildable from</th><th>to</th><th class=l>moves</th></tr>";
  for (const DimensionCheckSection& s : sections)
    body += fmt::format(
        "<tr><td class=l>{}</td><td>{} {}</td><td>{}</td><td>{:.4f}</td><td>{:.4f}</td>"
        "<td class=l>{} face{}</td></tr>",
        escapeHtml(s.name), s.nominal, s.unit, s.step, s.buildable_low, s.buildable_high,
        s.moved.size(), s.moved.size() == 1 ? "" : "s");
  body += "</table>";
  for (const DimensionCheckSection& s : sections) {
    body += fmt::format("<h2>{}</h2><p>nominal {} {}; buildable from {:.4f} ({}) to {:.4f} "
                        "({}).</p>",
                        escapeHtml(s.name), s.nominal, s.unit, s.buildable_low,
                        escapeHtml(s.low_reason), s.buildable_high, escapeHtml(s.high_reason));
    const auto list = [&](const char* what, const std::vector<std::string>& faces) {
      if (faces.empty()) return;
      body += fmt::format("<p>{}:</p><ul>", what);
      for (const std::string& face : faces) body += "<li>" + escapeHtml(face) + "</li>";
      body += "</ul>";
    };
    list("Moves", s.moved);
    list("Stretches (their edges move with the faces moved)", s.stretched);
    if (s.pictures.empty()) continue;
    body += "<div class=\"views\">";
    for (const PartPicture& picture : s.pictures)
      body += figure(picture, [](int) { return std::string(); });
    body += "</div>";
  }
  return page(title, body);
}

}  // namespace xgauge
