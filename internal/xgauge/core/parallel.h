// Thread control. Every parallel loop in xgauge produces the same numbers at
// any thread count (fixed work partitions, fixed reduction order).
#pragma once

#include <memory>

namespace xgauge {

// Limits oneTBB to `threads` worker threads for the lifetime of the returned
// object (0 = all cores).
class ThreadLimit {
 public:
  explicit ThreadLimit(int threads);
  ~ThreadLimit();
  ThreadLimit(const ThreadLimit&) = delete;
  ThreadLimit& operator=(const ThreadLimit&) = delete;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace xgauge
