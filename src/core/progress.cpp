#include "xgauge/core/progress.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <unistd.h>

namespace xgauge {

namespace {
std::atomic<bool> g_progress_enabled{true};
}

void setProgressEnabled(bool enabled) { g_progress_enabled = enabled; }
bool progressEnabled() { return g_progress_enabled; }

ProgressBar::ProgressBar(std::string label, int64_t total)
    : label_(std::move(label)),
      total_(std::max<int64_t>(total, 1)),
      visible_(progressEnabled() && ::isatty(STDERR_FILENO) == 1),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {
  if (visible_) draw(0, false);
}

ProgressBar::~ProgressBar() { finish(); }

void ProgressBar::advance(int64_t steps) {
  const int64_t done = done_.fetch_add(steps) + steps;
  if (!visible_) return;
  const auto now = std::chrono::steady_clock::now();
  std::unique_lock lock(draw_mutex_, std::try_to_lock);
  if (!lock.owns_lock() || finished_) return;
  if (now - last_draw_ < std::chrono::milliseconds(100) && done < total_) return;
  last_draw_ = now;
  draw(done, false);
}

void ProgressBar::finish() {
  std::lock_guard lock(draw_mutex_);
  if (finished_) return;
  finished_ = true;
  if (visible_) {
    draw(done_.load(), true);
    std::fputc('\n', stderr);
  }
}

std::string ProgressBar::formatDuration(double seconds) {
  if (seconds < 60) return fmt::format("{:.1f}s", seconds);
  const auto whole = static_cast<int64_t>(std::llround(seconds));
  if (whole < 3600) return fmt::format("{}m{:02d}s", whole / 60, whole % 60);
  return fmt::format("{}h{:02d}m", whole / 3600, (whole % 3600) / 60);
}

void ProgressBar::draw(int64_t done, bool final) {
  done = std::min(done, total_);
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double fraction = static_cast<double>(done) / static_cast<double>(total_);
  constexpr int kWidth = 30;
  const int filled = static_cast<int>(fraction * kWidth);
  std::string bar(static_cast<size_t>(filled), '#');
  bar.resize(kWidth, '.');
  std::string tail;
  if (final) {
    tail = fmt::format("done in {}", formatDuration(elapsed));
  } else if (done > 0) {
    tail = fmt::format("ETA {}", formatDuration(elapsed * (1.0 - fraction) / fraction));
  }
  std::fprintf(stderr, "\r%s [%s] %3d%% %lld/%lld %s\033[K", label_.c_str(), bar.c_str(),
               static_cast<int>(fraction * 100.0), static_cast<long long>(done),
               static_cast<long long>(total_), tail.c_str());
  std::fflush(stderr);
}

}  // namespace xgauge
