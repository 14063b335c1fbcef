#include "xgauge/core/parallel.h"

#include "xgauge/core/error.h"

#include <tbb/global_control.h>
#include <tbb/info.h>

#include <optional>

namespace xgauge {

struct ThreadLimit::Impl {
  std::optional<tbb::global_control> control;
};

ThreadLimit::ThreadLimit(int threads) : impl_(std::make_unique<Impl>()) {
  if (threads < 0) fail("thread count must be >= 0, got {}", threads);
  if (threads > 0)
    impl_->control.emplace(tbb::global_control::max_allowed_parallelism,
                           static_cast<size_t>(threads));
}

ThreadLimit::~ThreadLimit() = default;

}  // namespace xgauge
