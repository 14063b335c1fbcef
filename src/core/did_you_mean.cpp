#include "xgauge/core/did_you_mean.h"

#include <fmt/format.h>

#include <algorithm>

namespace xgauge {

// Optimal string alignment (Damerau-Levenshtein without repeated edits of a
// substring): a swap of two neighbours is one edit, so "sotre" is one edit
// from "store" and two from "source".
size_t editDistance(std::string_view a, std::string_view b) {
  std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
  for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (size_t i = 1; i <= a.size(); ++i)
    for (size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1,
                          d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
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
