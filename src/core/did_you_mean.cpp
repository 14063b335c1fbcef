#include "xgauge/core/did_you_mean.h"

#include <fmt/format.h>

#include <algorithm>

namespace xgauge {

size_t editDistance(std::string_view a, std::string_view b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

std::string didYouMean(std::string_view key, const std::vector<std::string_view>& known) {
  std::string hint;
  size_t best = 3;
  for (std::string_view k : known) {
    const size_t d = editDistance(key, k);
    if (d < best) best = d, hint = fmt::format("; did you mean '{}'?", k);
  }
  return hint;
}

}  // namespace xgauge
