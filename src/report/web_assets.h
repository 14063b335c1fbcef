// The files the HTML reports inline (report/html.h), compiled into the
// library by cmake/embed_files.cmake from src/report/web/ and the vendored
// uPlot in third_party/uplot (scripts/fetch-web-deps.sh pins and checks it).
#pragma once

#include <string_view>

namespace xgauge::web {

extern const std::string_view kUplotJs;       // uPlot.iife.min.js
extern const std::string_view kUplotCss;      // uPlot.min.css
extern const std::string_view kUplotLicense;  // its MIT licence, inlined with it
extern const std::string_view kReportJs;      // src/report/web/report.js
extern const std::string_view kReportCss;     // src/report/web/report.css
extern const std::string_view kSpcJs;         // src/report/web/spc.js: the SPC page

}  // namespace xgauge::web
