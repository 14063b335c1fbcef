// The inspection report: one self-contained HTML page per measurement,
// calibration and study (report.html in the output folder), which opens
// offline in any browser. The page carries its data as one JSON block (the
// run's result JSON, unchanged, plus the pictures and context a reader
// needs); the inlined script src/report/web/report.js builds every table and
// chart from it, with the vendored chart library uPlot (third_party/uplot,
// MIT, its licence inlined with it). Nothing is fetched: a Content Security
// Policy forbids every request but inline scripts, styles and data: images.
// docs/formats.md describes the page and its data.
#pragma once

#include "xgauge/image/image.h"
#include "xgauge/image/preview.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <string_view>

namespace xgauge {

// The kinds of page; report.js draws each from its data (spc: spc.js,
// production/spc_report.h).
enum class ReportKind { kMeasurement, kCalibration, kStudy, kSpc };
std::string_view reportKindName(ReportKind kind);  // "measurement", ..., "spc"

// The whole page: `data` is embedded as JSON (every '<' escaped, so no
// string in it can end the script element); `title` is the page title.
std::string reportPage(ReportKind kind, std::string_view title, const nlohmann::json& data);
// reportPage() written atomically to `path`.
void writeReport(const std::filesystem::path& path, ReportKind kind, std::string_view title,
                 const nlohmann::json& data);

// Text for an HTML element or attribute: & < > " as entities.
std::string escapeHtml(std::string_view text);

// The current time, UTC, ISO 8601 to the second ("2026-11-30T14:55:02Z"):
// when a page was written.
std::string utcTimestamp();

// Base64 data: URI of PNG bytes (OpenSSL's encoder).
std::string pngDataUri(const std::string& png);

// A picture of `image`, whose pixel (0, 0) is the detector's pixel
// (at.x, at.y) (at.width and at.height: the image's size), box-averaged down
// by the smallest integer factor that brings its longer side to at most
// `max_side` pixels: {"uri", "at": [x, y, w, h], "factor"}. Grey under
// `window`, or, for residualPicture(), the diverging map of
// image/preview.h from -scale (blue) to +scale (red). Non-finite pixels are
// black.
nlohmann::json greyPicture(const Image& image, const PixelRect& at, const GreyWindow& window,
                           int max_side);
nlohmann::json residualPicture(const Image& residual, const PixelRect& at, double scale,
                               int max_side);

// The diverging map of residualPicture() at t = -1, -0.8, .. 1 as CSS
// colours ("rgb(5,48,97)"), for the page's colour bar.
nlohmann::json divergingStops();

// A symmetric colour scale for residuals: the 99.5th percentile of |r| over
// every finite pixel of `images`, rounded up to 1, 2 or 5 x 10^k, so that a
// few outliers do not wash out the rest and the colour bar reads in round
// numbers. At least 1e-6.
double residualScale(const std::vector<const Image*>& images);

}  // namespace xgauge
