// libFuzzer target: xgauge::readDiconde (internal/xgauge/image/diconde.h) on
// arbitrary bytes written to a scratch file. Expected outcomes: an Image, or
// xgauge::Error. Anything else (a crash inside DCMTK included) is a finding.
#include "fuzz_common.h"

#include "xgauge/core/error.h"
#include "xgauge/image/diconde.h"

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
  const auto path = xgauge_fuzz::writeScratch("input.dcm", data, size);
  try {
    std::string sha256;
    int frames = 0;
    const xgauge::Image image =
        xgauge::readDiconde(path, (size % 2) ? &sha256 : nullptr, nullptr, &frames);
    FUZZ_ASSERT(image.width() > 0 && image.height() > 0, "readDiconde returned an empty image");
    FUZZ_ASSERT(image.size() == static_cast<size_t>(image.width()) * image.height(),
                "image size does not match its dimensions");
    FUZZ_ASSERT(frames >= 1, "no frame count");
    FUZZ_ASSERT((size % 2) == 0 || sha256.size() == 64, "readDiconde gave no SHA-256");
    for (const float value : image.pixels())
      FUZZ_ASSERT(std::isfinite(value), "readDiconde returned a non-finite pixel");
  } catch (const xgauge::Error&) {
    // Bad input reported as documented.
  }
  return 0;
}
