// The front door's process settings (xgauge/runtime.h) over core's logging,
// progress, thread pool, output cleanup and image reader limits.
#include "xgauge/runtime.h"

#include "xgauge/core/did_you_mean.h"
#include "xgauge/core/log.h"
#include "xgauge/core/memory.h"
#include "xgauge/core/output.h"
#include "xgauge/core/parallel.h"
#include "xgauge/core/progress.h"
#include "xgauge/image/tiff.h"

#include <spdlog/spdlog.h>

namespace xgauge {

static_assert(kDefaultMaxImageBytes == kDefaultTiffMemoryLimit);

const char* RunTerminationToString(RunTermination type) {
  return type == RunTermination::kDone ? "done" : "failure";
}

void PrepareProcess() {
  installInterruptCleanup();
  keepLargeBlocksInHeap();
}

struct RuntimeScope::Impl {
  explicit Impl(int threads) : limit(threads) {}
  ThreadLimit limit;
};

RuntimeScope::RuntimeScope(const RuntimeOptions& options) {
  setupLogging(options.log_level == LogLevel::kQuiet     ? Verbosity::kQuiet
               : options.log_level == LogLevel::kVerbose ? Verbosity::kVerbose
                                                         : Verbosity::kNormal);
  setProgressEnabled(options.progress);
  impl_ = std::make_unique<Impl>(options.threads);
  setTiffMemoryLimit(options.max_image_bytes);
}

RuntimeScope::~RuntimeScope() = default;

void LogMessage(Severity severity, const std::string& message) {
  switch (severity) {
    case Severity::kInfo:
      spdlog::info("{}", message);
      break;
    case Severity::kWarning:
      spdlog::warn("{}", message);
      break;
    case Severity::kError:
      spdlog::error("{}", message);
      break;
  }
}

std::string NearestName(const std::string& name, const std::vector<std::string>& known) {
  std::string nearest;
  size_t best = 3;
  for (const std::string& k : known)
    if (const size_t d = editDistance(name, k); d < best) best = d, nearest = k;
  return nearest;
}

}  // namespace xgauge
