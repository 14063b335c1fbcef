#include "xgauge/image/radiograph.h"

#include "xgauge/core/error.h"
#include "xgauge/image/bad_pixels.h"
#include "xgauge/image/stats.h"

#include <algorithm>

namespace xgauge {

NormalizedRadiograph normalizeRadiograph(Image raw, const RadiographFrames& frames,
                                         const std::optional<PixelRect>& white,
                                         ClampPolicy clamp, const std::string& name) {
  XG_CHECK((frames.dark == nullptr) == (frames.flat == nullptr), "give both dark and flat");
  NormalizedRadiograph out;
  out.image = std::move(raw);
  if (frames.dark) {
    try {
      out.image =
          flatFieldCorrectRepairing(out.image, *frames.dark, *frames.flat, &out.repaired_pixels);
    } catch (const Error& e) {
      fail("{} with its dark and flat frames: {}", name, e.message());
    }
  }
  if (white) {
    if (white->empty() || !out.image.rect().contains(*white))
      fail("{}: white region {} is not a non-empty region inside the {}x{} image", name,
           toString(*white), out.image.width(), out.image.height());
    out.white_mean = meanOf(out.image, *white);
    if (!(out.white_mean > 0.0))
      fail("{}: the white region {} has mean {} (must be positive: is it in the open beam?)", name,
           toString(*white), out.white_mean);
    const float scale = static_cast<float>(1.0 / out.white_mean);
    for (float& p : out.image.pixels()) p *= scale;
  }
  if (clamp == ClampPolicy::kAtOne) clampToOne(out.image);
  return out;
}

void clampToOne(Image& image) {
  for (float& p : image.pixels()) p = std::min(p, 1.0f);
}

}  // namespace xgauge
