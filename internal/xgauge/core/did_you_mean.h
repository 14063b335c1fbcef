// "Did you mean" hints for a misspelled key: the known key nearest by edit
// distance (optimal string alignment: Levenshtein with a swap of neighbours
// as one edit), within two edits.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace xgauge {

size_t editDistance(std::string_view a, std::string_view b);

// "; did you mean 'width'?" for the known key within two edits of `key`
// (the nearest; the first of equals), or "".
std::string didYouMean(std::string_view key, const std::vector<std::string_view>& known);

}  // namespace xgauge
