#include "xgauge/core/progress.h"

#include <gtest/gtest.h>

namespace xgauge {
namespace {

TEST(Progress, FormatsDurations) {
  EXPECT_EQ(ProgressBar::formatDuration(3.24), "3.2s");
  EXPECT_EQ(ProgressBar::formatDuration(65.0), "1m05s");
  EXPECT_EQ(ProgressBar::formatDuration(3725.0), "1h02m");
}

TEST(Progress, SilentWhenDisabled) {
  setProgressEnabled(false);
  ProgressBar bar("work", 10);
  EXPECT_FALSE(bar.visible());
  bar.advance(10);
  setProgressEnabled(true);
}

}  // namespace
}  // namespace xgauge
