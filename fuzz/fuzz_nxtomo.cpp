// libFuzzer target: xgauge::readNxTomoInProcess (internal/xgauge/image/nxtomo.h) on
// arbitrary bytes written to a scratch .nxs file, with a frame selector
// chosen by the input's length (none, dark, flat, projection=0, angle=0).
// Expected outcomes: an Image, or xgauge::Error. Anything else (a crash
// inside libhdf5 included) is a finding.
#include "fuzz_common.h"

#include "xgauge/core/error.h"
#include "xgauge/image/nxtomo.h"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  xgauge_fuzz::quietLogging();
  xgauge_fuzz::scratchDir();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const char* const kSelectors[] = {"", "dark", "flat", "projection=0", "angle=0"};
  const auto path = xgauge_fuzz::writeScratch("input.nxs", data, size);
  try {
    int frames = 0;
    const xgauge::Image image =
        xgauge::readNxTomoInProcess(path, kSelectors[size % 5], nullptr, nullptr, &frames);
    FUZZ_ASSERT(image.width() > 0 && image.height() > 0, "readNxTomo returned an empty image");
    FUZZ_ASSERT(image.size() == static_cast<size_t>(image.width()) * image.height(),
                "image size does not match its dimensions");
    FUZZ_ASSERT(frames >= 1, "no frame count");
    for (const float value : image.pixels())
      FUZZ_ASSERT(std::isfinite(value), "readNxTomo returned a non-finite pixel");
  } catch (const xgauge::Error&) {
    // Bad input reported as documented.
  }
  return 0;
}
