#include "xgauge/xray/detector_file.h"

#include "xgauge/core/config.h"

#include <fmt/format.h>

namespace xgauge {

DetectorFile loadDetectorFile(const std::filesystem::path& path) {
  const ConfigNode root = ConfigNode::loadFile(path);
  DetectorFile out;
  out.file = path;
  if (auto halo = root.find("halo")) out.halo = ScatterModel::fromConfig(halo->at("scatter"));
  if (auto lag = root.find("lag_fraction")) {
    out.lag_fraction = lag->at("value").number(0.0, 0.5);
    out.lag_fraction_uncertainty = lag->at("uncertainty").number(0.0, 0.5);
  }
  if (auto crosstalk = root.find("crosstalk")) {
    out.column_crosstalk = crosstalk->at("value").number(0.0, 0.2);
    out.column_crosstalk_uncertainty = crosstalk->at("uncertainty").number(0.0, 0.2);
  }
  if (auto bad = root.find("bad_pixels"))
    out.bad_pixels = path.parent_path() / bad->get<std::string>("file");
  // The rest (candidates, inputs) is the record, not read.
  root.json();
  return out;
}

ImageT<uint8_t> loadBadPixelMask(const std::filesystem::path& path, int columns, int rows) {
  const ConfigNode root = ConfigNode::loadFile(path);
  if (root.at("columns").integer(1, 65536) != columns)
    root.at("columns").fail(fmt::format("the machine's detector has {} columns", columns));
  if (root.at("rows").integer(1, 65536) != rows)
    root.at("rows").fail(fmt::format("the machine's detector has {} rows", rows));
  ImageT<uint8_t> mask(columns, rows, 0);
  for (const char* kind : {"dead", "hot", "noisy"}) {
    const ConfigNode list = root.at(kind);
    for (size_t i = 0; i < list.size(); ++i) {
      const ConfigNode pixel = list[i];
      if (pixel.size() != 2) pixel.fail("expected [u, v]");
      const auto u = static_cast<int>(pixel[0].integer(0, columns - 1));
      const auto v = static_cast<int>(pixel[1].integer(0, rows - 1));
      mask(u, v) = 1;
    }
  }
  root.finish();
  return mask;
}

std::optional<DetectorFile> detectorFileOf(const std::filesystem::path& machine_file) {
  const ConfigNode root = ConfigNode::loadFile(machine_file);
  const auto detector = root.find("detector");
  if (!detector) return std::nullopt;
  const auto name = detector->find("characterization");
  if (!name) return std::nullopt;
  return loadDetectorFile(machine_file.parent_path() / name->string());
}

}  // namespace xgauge
