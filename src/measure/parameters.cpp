#include "xgauge/measure/parameters.h"

#include "xgauge/core/error.h"

namespace xgauge {

int ParameterLayout::add(std::string_view block, ParameterKind kind,
                         const std::vector<std::string>& components,
                         const std::vector<double>& lower, const std::vector<double>& upper,
                         const std::vector<double>& start) {
  XG_CHECK(!hasBlock(block), "parameter block '{}' added twice", block);
  XG_CHECK(components.size() == lower.size() && lower.size() == upper.size() &&
               upper.size() == start.size(),
           "block '{}': sizes differ", block);
  const int first = size();
  for (size_t k = 0; k < components.size(); ++k) {
    XG_CHECK(lower[k] <= start[k] && start[k] <= upper[k], "{}/{}: start {} outside [{}, {}]",
             block, components[k], start[k], lower[k], upper[k]);
    parameters_.push_back(
        {std::string(block) + "/" + components[k], kind, lower[k], upper[k], start[k]});
    lower_.push_back(lower[k]), upper_.push_back(upper[k]), start_.push_back(start[k]);
  }
  blocks_.push_back({std::string(block), first, static_cast<int>(components.size())});
  return first;
}

bool ParameterLayout::hasBlock(std::string_view block) const {
  for (const Block& b : blocks_)
    if (b.name == block) return true;
  return false;
}

std::vector<int> ParameterLayout::block(std::string_view block) const {
  std::vector<int> out;
  for (const Block& b : blocks_)
    if (b.name == block)
      for (int i = 0; i < b.count; ++i) out.push_back(b.first + i);
  return out;
}

int ParameterLayout::index(std::string_view name) const {
  for (size_t i = 0; i < parameters_.size(); ++i)
    if (parameters_[i].name == name) return static_cast<int>(i);
  XG_CHECK(false, "no parameter named '{}'", name);
  return -1;
}

}  // namespace xgauge
