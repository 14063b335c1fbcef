#include "xgauge/image/radiograph_file.h"

#include "xgauge/core/error.h"
#include "xgauge/image/diconde.h"
#include "xgauge/image/nxtomo.h"
#include "xgauge/image/raw_file.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <fstream>
#include <optional>

namespace xgauge {
namespace {

namespace fs = std::filesystem;

constexpr std::array<unsigned char, 8> kHdf5Signature = {0x89, 'H',  'D',  'F',
                                                         '\r', '\n', 0x1a, '\n'};

// The format a file's first bytes declare; nullopt for none (raw).
std::optional<RadiographFormat> sniff(const fs::path& path, const SourceLocation& where) {
  std::ifstream in(path, std::ios::binary);
  if (!in) failAt(where, "cannot open the file");
  std::array<char, 132> head{};
  in.read(head.data(), head.size());
  const auto got = static_cast<size_t>(in.gcount());
  const auto starts = [&](std::string_view magic) {
    return got >= magic.size() && std::equal(magic.begin(), magic.end(), head.begin());
  };
  using namespace std::string_view_literals;
  if (starts("II*\0"sv) || starts("MM\0*"sv) || starts("II+\0"sv) || starts("MM\0+"sv))
    return RadiographFormat::kTiff;
  if (got >= kHdf5Signature.size() &&
      std::equal(kHdf5Signature.begin(), kHdf5Signature.end(),
                 reinterpret_cast<const unsigned char*>(head.data())))
    return RadiographFormat::kNxTomo;
  if (got >= 132 && std::string_view(head.data() + 128, 4) == "DICM")
    return RadiographFormat::kDiconde;
  return std::nullopt;
}

std::string lowerExtension(const fs::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension;
}

}  // namespace

const char* toString(RadiographFormat format) {
  switch (format) {
    case RadiographFormat::kTiff:
      return "TIFF";
    case RadiographFormat::kRaw:
      return "raw";
    case RadiographFormat::kNxTomo:
      return "NXtomo";
    case RadiographFormat::kDiconde:
      return "DICONDE";
  }
  return "?";
}

RadiographFile readRadiograph(const fs::path& path, std::string* sha256,
                              const ExpectedImageSize* expected) {
  SourceLocation where = SourceLocation::inFile(path.string());
  std::error_code ec;
  fs::path file = path;
  std::string selector;
  if (!fs::exists(path, ec)) {
    // "scan.nxs#dark": a frame selector after the file's name.
    const std::string text = path.string();
    const auto hash = text.rfind('#');
    if (hash == std::string::npos || !fs::exists(fs::path(text.substr(0, hash)), ec))
      throw Error(ec ? "cannot access the file: " + ec.message() : "file does not exist", where);
    file = text.substr(0, hash);
    selector = text.substr(hash + 1);
  }
  if (fs::is_directory(file, ec)) throw Error("is a folder, not a radiograph file", where);

  RadiographFile out;
  const std::optional<RadiographFormat> format = sniff(file, where);
  if (!selector.empty() && format != RadiographFormat::kNxTomo)
    failAt(where, "'#{}' selects frames of an NXtomo (HDF5) file, but {} is not one", selector,
           file.string());
  out.format = format.value_or(RadiographFormat::kRaw);
  switch (out.format) {
    case RadiographFormat::kTiff:
      out.image = readTiff(file, sha256, expected, &out.frames);
      break;
    case RadiographFormat::kNxTomo:
      out.image = readNxTomo(file, selector, sha256, expected, &out.frames);
      break;
    case RadiographFormat::kDiconde:
      out.image = readDiconde(file, sha256, expected, &out.frames);
      break;
    case RadiographFormat::kRaw:
      out.image = readRawRadiograph(file, sha256, expected, &out.frames);
      break;
  }
  return out;
}

RadiographFormat writableFormatOf(const fs::path& path) {
  const std::string extension = lowerExtension(path);
  if (extension == ".tif" || extension == ".tiff") return RadiographFormat::kTiff;
  if (extension == ".raw") return RadiographFormat::kRaw;
  if (extension == ".nxs" || extension == ".h5" || extension == ".hdf5" || extension == ".nx5")
    return RadiographFormat::kNxTomo;
  if (extension == ".dcm" || extension == ".dicom") return RadiographFormat::kDiconde;
  failAt(SourceLocation::inFile(path.string()),
         "cannot tell the format from the extension '{}': .tif/.tiff (TIFF), .raw (raw + .raw.json "
         "sidecar), .nxs/.h5/.hdf5/.nx5 (NXtomo) or .dcm/.dicom (DICONDE)",
         extension);
}

void writeRadiograph(const fs::path& path, const Image& image, TiffFormat samples) {
  switch (writableFormatOf(path)) {
    case RadiographFormat::kTiff:
      writeTiff(path, image, samples);
      return;
    case RadiographFormat::kRaw:
      writeRawRadiograph(path, image, samples);
      return;
    case RadiographFormat::kNxTomo: {
      const NxTomoFrame frame{&image, 0, 0.0};
      writeNxTomo(path, std::span(&frame, 1), samples);
      return;
    }
    case RadiographFormat::kDiconde:
      writeDiconde(path, image, samples);
      return;
  }
}

}  // namespace xgauge
