// libFuzzer target: xgauge::readTiff (internal/xgauge/image/tiff.h) on
// arbitrary bytes written to a scratch file. Expected outcomes: an Image, or
// xgauge::Error. Anything else (another exception, a sanitizer report, an
// abort, an allocation over -malloc_limit_mb) is a finding.
#include "fuzz_common.h"

#include "xgauge/core/error.h"
#include "xgauge/image/tiff.h"

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
  const auto path = xgauge_fuzz::writeScratch("input.tif", data, size);
  try {
    // Half the inputs also hash the file through the same descriptor.
    std::string sha256;
    const xgauge::Image image = xgauge::readTiff(path, (size % 2) ? &sha256 : nullptr);
    FUZZ_ASSERT(image.width() > 0 && image.height() > 0, "readTiff returned an empty image");
    FUZZ_ASSERT(image.size() == static_cast<size_t>(image.width()) * image.height(),
                "image size does not match its dimensions");
    FUZZ_ASSERT(image.size() <= (size_t{1} << 30), "readTiff returned more than 2^30 pixels");
    FUZZ_ASSERT((size % 2) == 0 || sha256.size() == 64, "readTiff gave no SHA-256");
    for (const float value : image.pixels())
      FUZZ_ASSERT(std::isfinite(value), "readTiff returned a non-finite pixel");
  } catch (const xgauge::Error&) {
    // Bad input reported as documented.
  }
  return 0;
}
