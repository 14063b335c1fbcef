// The front door's calls turn the library's errors into a summary's
// termination and message: only the likes of std::bad_alloc propagate.
#pragma once

#include "xgauge/runtime.h"

#include <exception>
#include <new>

namespace xgauge::api {

// Runs `work` (which returns a Summary); an exception other than
// std::bad_alloc becomes a Summary with kFailure and the exception's text.
template <typename Summary, typename Work>
Summary guarded(Work&& work) {
  try {
    return work();
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    Summary failed;
    failed.termination = RunTermination::kFailure;
    failed.message = e.what();
    return failed;
  }
}

}  // namespace xgauge::api
