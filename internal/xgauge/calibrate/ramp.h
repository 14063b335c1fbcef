// Finding a wedge's ramp in a normalized radiograph (thesis 3.4a, steps 2-4;
// docs/method.md),
// which the thesis did by eye: the columns that see the ramp, and the rows
// where it starts (the thin end) and ends (the thick end).
//
// The wedge is expected with its ramp running along the image columns (its
// thickness changing from row to row), the thin end at the top or at the
// bottom, open beam beyond both ends:
//
//   row profile   1 (air) | step down to I(x_min) | smooth fall to I(x_max) | rise to 1 (air)
//
// Columns: on a copy about 256 px wide, every column whose shadow is
// darker at its far end than at its near end by at least half of the
// strongest such column's contrast, in one contiguous run around the
// strongest; the run is shrunk by 15 % on each side to keep clear of the
// pocket's edges. Rows, on the mean over those columns of every row:
//   thin end   the step from the open beam: the row where the profile
//              crosses half-way between the open beam (median of rows 3..12
//              outside) and the ramp (median of rows 3..12 inside);
//   thick end  the kink where the fall turns into the rise back to the open
//              beam: the intersection of straight lines fitted to the ramp
//              before the minimum and to the first 5 % of the rise after it;
//              where the rise is a step (fewer than 4 rows), its half-way
//              crossing as at the thin end.
// Rows are continuous coordinates: the centre of row r is r + 0.5.
#pragma once

#include "xgauge/image/image.h"

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace xgauge {

struct RampOptions {
  std::optional<std::array<int, 2>> columns;  // [begin, end): override the automatic band
  std::optional<std::array<double, 2>> rows;  // [thin end, thick end]: override the detection
};

struct RampDetection {
  int column_begin = 0, column_end = 0;  // columns averaged, [begin, end)
  bool automatic_columns = true, automatic_rows = true;
  double thin_row = 0.0;        // continuous row coordinate of the thin end
  double thick_row = 0.0;       // continuous row coordinate of the thick end
  std::vector<double> profile;  // mean over the band of every row
  double row_noise = 0.0;       // robust noise of one profile value (from second differences)
  bool thinEndOnTop() const { return thin_row < thick_row; }
};

// Finds the ramp in `normalized` (open beam = 1; ideally with the detector's
// scatter removed). `name` names the image in errors. Throws Error when there
// is no ramp (no column band whose shadow darkens along it, or a band profile
// without a long shadow), when the ramp runs off the image (it must span the
// whole thickness range: open beam beyond both ends), or when an override lies
// outside the image.
RampDetection detectRamp(const Image& normalized, const RampOptions& options,
                         const std::string& name);

}  // namespace xgauge
