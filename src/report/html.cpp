#include "xgauge/report/html.h"

#include "web_assets.h"

#include "xgauge/core/atomic_file.h"
#include "xgauge/core/error.h"
#include "xgauge/version.h"

#include <fmt/chrono.h>
#include <openssl/evp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

namespace xgauge {
namespace {

// The box average of `image` over factor x factor blocks (partial blocks at
// the right and bottom edges average what they have); non-finite pixels
// stay out of the average, and a block of none is NaN.
Image boxDown(const Image& image, int factor) {
  if (factor <= 1) return image;
  const int w = (image.width() + factor - 1) / factor, h = (image.height() + factor - 1) / factor;
  Image out(w, h, 0.0f);
  for (int by = 0; by < h; ++by)
    for (int bx = 0; bx < w; ++bx) {
      double sum = 0.0;
      int n = 0;
      for (int y = by * factor; y < std::min(image.height(), (by + 1) * factor); ++y)
        for (int x = bx * factor; x < std::min(image.width(), (bx + 1) * factor); ++x)
          if (std::isfinite(image(x, y))) sum += static_cast<double>(image(x, y)), ++n;
      out(bx, by) = n > 0 ? static_cast<float>(sum / n) : std::nanf("");
    }
  return out;
}

int factorFor(const Image& image, int max_side) {
  const int side = std::max(image.width(), image.height());
  return std::max(1, (side + max_side - 1) / std::max(1, max_side));
}

nlohmann::json pictureJson(const std::string& png, const PixelRect& at, int factor) {
  return {{"uri", pngDataUri(png)}, {"at", {at.x, at.y, at.width, at.height}}, {"factor", factor}};
}

}  // namespace

std::string escapeHtml(std::string_view text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string_view reportKindName(ReportKind kind) {
  switch (kind) {
    case ReportKind::kMeasurement:
      return "measurement";
    case ReportKind::kCalibration:
      return "calibration";
    case ReportKind::kStudy:
      return "study";
    case ReportKind::kSpc:
      return "spc";
  }
  return "unknown";
}

std::string reportPage(ReportKind kind, std::string_view title, const nlohmann::json& data) {
  // '<' never appears outside strings in JSON; as \u003c it cannot close
  // the script element, and JSON.parse reads it back as '<'.
  std::string json;
  for (char c : data.dump()) {
    if (c == '<')
      json += "\\u003c";
    else
      json += c;
  }
  std::string page;
  page.reserve(json.size() + web::kUplotJs.size() + web::kReportJs.size() + 8192);
  page += "<!DOCTYPE html>\n<html lang=\"en\" data-report=\"";
  page += reportKindName(kind);
  page += "\">\n<head>\n<meta charset=\"utf-8\">\n";
  // Nothing but what the page carries: no request leaves it.
  page +=
      "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; "
      "img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'\">\n";
  page += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n";
  page += "<meta name=\"generator\" content=\"xgauge " XGAUGE_VERSION_STRING "\">\n";
  page += "<title>" + escapeHtml(title) + "</title>\n";
  // Errors anywhere below are collected before any other script runs.
  page +=
      "<script>window.xgaugeErrors = []; window.addEventListener('error', function (e) { "
      "window.xgaugeErrors.push(String(e.message)); });</script>\n";
  page += "<style>\n";
  page += web::kUplotCss;
  page += "\n</style>\n<style>\n";
  page += web::kReportCss;
  page += "\n</style>\n</head>\n<body>\n";
  page +=
      "<noscript>This report draws itself with JavaScript. Its numbers are in the JSON "
      "files beside it.</noscript>\n<main id=\"report\"></main>\n";
  page += "<script type=\"application/json\" id=\"xgauge-data\">";
  page += json;
  page +=
      "</script>\n<!--\nuPlot (https://github.com/leeoniya/uPlot; its version is on the "
      "script's first line), inlined below under its licence:\n\n";
  page += escapeHtml(web::kUplotLicense);
  page += "-->\n<script>\n";
  page += web::kUplotJs;
  page += "\n</script>\n<script>\n";
  if (kind == ReportKind::kSpc) {
    page += web::kSpcJs;
    page += "\n</script>\n<script>\n";
  }
  page += web::kReportJs;
  page += "\n</script>\n</body>\n</html>\n";
  return page;
}

void writeReport(const std::filesystem::path& path, ReportKind kind, std::string_view title,
                 const nlohmann::json& data) {
  writeFileAtomically(path, reportPage(kind, title, data));
}

std::string utcTimestamp() {
  return fmt::format("{:%Y-%m-%dT%H:%M:%SZ}",
                     std::chrono::floor<std::chrono::seconds>(std::chrono::system_clock::now()));
}

std::string pngDataUri(const std::string& png) {
  std::string base64(4 * ((png.size() + 2) / 3) + 1, '\0');
  const int n = EVP_EncodeBlock(reinterpret_cast<unsigned char*>(base64.data()),
                                reinterpret_cast<const unsigned char*>(png.data()),
                                static_cast<int>(png.size()));
  base64.resize(static_cast<size_t>(std::max(0, n)));
  return "data:image/png;base64," + base64;
}

nlohmann::json greyPicture(const Image& image, const PixelRect& at, const GreyWindow& window,
                           int max_side) {
  const int factor = factorFor(image, max_side);
  const Image small = boxDown(image, factor);
  std::vector<uint8_t> pixels;
  pixels.reserve(static_cast<size_t>(small.width()) * static_cast<size_t>(small.height()));
  for (int y = 0; y < small.height(); ++y)
    for (int x = 0; x < small.width(); ++x)
      pixels.push_back(greyLevel(small(x, y), window.lo, window.hi));
  return pictureJson(encodePng(small.width(), small.height(), 1, pixels), at, factor);
}

nlohmann::json residualPicture(const Image& residual, const PixelRect& at, double scale,
                               int max_side) {
  XG_CHECK(std::isfinite(scale) && scale > 0.0, "residual scale {} is not > 0", scale);
  const int factor = factorFor(residual, max_side);
  const Image small = boxDown(residual, factor);
  std::vector<uint8_t> pixels;
  pixels.reserve(3 * static_cast<size_t>(small.width()) * static_cast<size_t>(small.height()));
  for (int y = 0; y < small.height(); ++y)
    for (int x = 0; x < small.width(); ++x) {
      const double v = small(x, y);
      const Rgb8 c = std::isfinite(v) ? divergingColor(v / scale) : Rgb8{0, 0, 0};
      pixels.insert(pixels.end(), {c.r, c.g, c.b});
    }
  return pictureJson(encodePng(small.width(), small.height(), 3, pixels), at, factor);
}

nlohmann::json divergingStops() {
  nlohmann::json out = nlohmann::json::array();
  for (int k = -5; k <= 5; ++k) {
    const Rgb8 c = divergingColor(k / 5.0);
    out.push_back(fmt::format("rgb({},{},{})", c.r, c.g, c.b));
  }
  return out;
}

double residualScale(const std::vector<const Image*>& images) {
  std::vector<float> magnitudes;
  for (const Image* image : images)
    for (int y = 0; y < image->height(); ++y)
      for (int x = 0; x < image->width(); ++x)
        if (std::isfinite((*image)(x, y))) magnitudes.push_back(std::abs((*image)(x, y)));
  if (magnitudes.empty()) return 1.0;
  const size_t k =
      std::min(magnitudes.size() - 1,
               static_cast<size_t>(std::ceil(0.995 * static_cast<double>(magnitudes.size() - 1))));
  std::nth_element(magnitudes.begin(), magnitudes.begin() + static_cast<std::ptrdiff_t>(k),
                   magnitudes.end());
  const double raw = std::max(1e-6, static_cast<double>(magnitudes[k]));
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  for (double step : {1.0, 2.0, 5.0, 10.0})
    if (raw <= step * decade * (1.0 + 1e-6)) return step * decade;  // float residuals
  return 10.0 * decade;
}

}  // namespace xgauge
