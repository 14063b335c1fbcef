// libFuzzer target: xgauge::readRawRadiograph (internal/xgauge/image/raw_file.h)
// on a raw file and its sidecar both taken from the input: the first two
// bytes (little-endian) give the sidecar's length, the sidecar's bytes
// follow (written as input.raw.json when they start with '{', else as
// input.raw.ini), and the rest is the raw file. Expected outcomes: an Image,
// or xgauge::Error. Anything else is a finding.
#include "fuzz_common.h"

#include "xgauge/core/error.h"
#include "xgauge/image/raw_file.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  xgauge_fuzz::quietLogging();
  xgauge_fuzz::scratchDir();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  const size_t sidecar_bytes = std::min<size_t>(size - 2, data[0] | (size_t{data[1]} << 8));
  const uint8_t* sidecar = data + 2;
  const bool json = sidecar_bytes > 0 && sidecar[0] == '{';
  std::error_code ignored;
  std::filesystem::remove(xgauge_fuzz::scratchDir() / (json ? "input.raw.ini" : "input.raw.json"),
                          ignored);
  xgauge_fuzz::writeScratch(json ? "input.raw.json" : "input.raw.ini", sidecar, sidecar_bytes);
  const auto path =
      xgauge_fuzz::writeScratch("input.raw", sidecar + sidecar_bytes, size - 2 - sidecar_bytes);
  try {
    std::string sha256;
    int frames = 0;
    const xgauge::Image image =
        xgauge::readRawRadiograph(path, (size % 2) ? &sha256 : nullptr, nullptr, &frames);
    FUZZ_ASSERT(image.width() > 0 && image.height() > 0,
                "readRawRadiograph returned an empty image");
    FUZZ_ASSERT(image.size() == static_cast<size_t>(image.width()) * image.height(),
                "image size does not match its dimensions");
    FUZZ_ASSERT(frames >= 1, "no frame count");
    FUZZ_ASSERT((size % 2) == 0 || sha256.size() == 64, "readRawRadiograph gave no SHA-256");
    for (const float value : image.pixels())
      FUZZ_ASSERT(std::isfinite(value), "readRawRadiograph returned a non-finite pixel");
  } catch (const xgauge::Error&) {
    // Bad input reported as documented.
  }
  return 0;
}
