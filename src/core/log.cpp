#include "xgauge/core/log.h"

#include <spdlog/sinks/stdout_color_sinks.h>

namespace xgauge {

void setupLogging(Verbosity verbosity) {
  auto logger = spdlog::stderr_color_mt("xgauge");
  logger->set_pattern("%^[%l]%$ %v");
  switch (verbosity) {
    case Verbosity::kQuiet: logger->set_level(spdlog::level::err); break;
    case Verbosity::kNormal: logger->set_level(spdlog::level::info); break;
    case Verbosity::kVerbose: logger->set_level(spdlog::level::debug); break;
  }
  spdlog::set_default_logger(logger);
}

}  // namespace xgauge
