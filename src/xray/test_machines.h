// Test helper: the reference parts' folder and a square test detector.
#pragma once

#include "xgauge/xray/machine.h"

#include <string>

namespace xgauge::testing {

inline const std::string kParts = std::string(XGAUGE_SOURCE_DIR) + "/parts/";

// size x size pixels of `pitch_mm`, source 1000 mm away, principal point at
// the centre.
inline Machine squareMachine(int size, double pitch_mm) {
  Machine m;
  m.source_detector_distance_mm = 1000.0;
  m.columns = m.rows = size;
  m.pitch_u_mm = m.pitch_v_mm = pitch_mm;
  m.cx_px = m.cy_px = 0.5 * size;
  return m;
}

}  // namespace xgauge::testing
