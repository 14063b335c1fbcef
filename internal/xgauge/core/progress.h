// A terminal progress bar on stderr with rate and ETA. Silent when stderr is
// not a terminal or when progress is disabled globally (--quiet). Thread
// safe: advance() may be called from worker threads.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace xgauge {

// Global switch set by the CLI's --quiet.
void setProgressEnabled(bool enabled);
bool progressEnabled();

class ProgressBar {
 public:
  ProgressBar(std::string label, int64_t total);
  ~ProgressBar();  // finishes the line
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  void advance(int64_t steps = 1);
  void finish();
  bool visible() const { return visible_; }

  // "1m05s", "3.2s": used for the ETA; exposed for tests.
  static std::string formatDuration(double seconds);

 private:
  void draw(int64_t done, bool final);

  std::string label_;
  int64_t total_;
  std::atomic<int64_t> done_{0};
  bool visible_;
  bool finished_ = false;
  std::mutex draw_mutex_;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
};

}  // namespace xgauge
