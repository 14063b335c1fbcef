// The named parameters of a measurement (in the manner of Mitsuba's
// `traverse`): every scalar the fit may vary has a name "<block>/<component>",
//   dim/<dimension>                    a dimension of the part (mm or deg)
//   <radiograph>/rotation/{rx,ry,rz}   free and rotated radiographs: Euler
//                                      angles (deg, R = Rz Ry Rx)
//   <radiograph>/position/{x,y,z}      the world position (mm) of the part's
//                                      reference centre
//   <radiograph>/axis/{azimuth,elevation}  translated radiographs: the
//                                      direction (deg) of the known move
//   material/fraction<k>, material/rate<k>  a calibration's free material
//   detector/{tilt_u,tilt_v,rotation}  a geometry calibration's free
//                                      detector pose (deg)
// and stages name what they free ("t03/rotation", "dim") instead of computing
// offsets into the parameter vector. The vector theta holds every parameter
// in the order they were added; fixed ones simply keep their value.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace xgauge {

enum class ParameterKind { kDimension, kRotation, kPosition, kAxis, kMaterial, kDetector };

struct Parameter {
  std::string name;  // "<block>/<component>"
  ParameterKind kind = ParameterKind::kDimension;
  double lower = 0.0, upper = 0.0;  // lower == upper: fixed
  double start = 0.0;
};

class ParameterLayout {
 public:
  // Appends the parameters of `block`, named "<block>/<component>"; returns
  // the index of the first. A block name must be new (XG_CHECK).
  int add(std::string_view block, ParameterKind kind,
          const std::vector<std::string>& components, const std::vector<double>& lower,
          const std::vector<double>& upper, const std::vector<double>& start);

  int size() const { return static_cast<int>(parameters_.size()); }
  const Parameter& operator[](int index) const { return parameters_[static_cast<size_t>(index)]; }
  const std::vector<double>& lower() const { return lower_; }
  const std::vector<double>& upper() const { return upper_; }
  const std::vector<double>& start() const { return start_; }

  bool hasBlock(std::string_view block) const;
  // The indices of a block, in order; empty for a block that was not added
  // (a known radiograph has no pose block).
  std::vector<int> block(std::string_view block) const;
  // The index of "<block>/<component>" (XG_CHECK that it exists).
  int index(std::string_view name) const;
  // Whether the parameter may vary (lower < upper).
  bool isFree(int index) const { return lower_[static_cast<size_t>(index)] < upper_[static_cast<size_t>(index)]; }

 private:
  struct Block {
    std::string name;
    int first = 0, count = 0;
  };
  std::vector<Parameter> parameters_;
  std::vector<Block> blocks_;
  std::vector<double> lower_, upper_, start_;
};

}  // namespace xgauge
