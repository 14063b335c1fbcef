// Logging through spdlog: messages go to stderr; --quiet keeps warnings and
// errors only, --verbose adds debug messages.
#pragma once

#include <spdlog/spdlog.h>

namespace xgauge {

enum class Verbosity { kQuiet, kNormal, kVerbose };
void setupLogging(Verbosity verbosity);

}  // namespace xgauge
