// Radiograph files in the shapes labs export, behind one entry point: the
// measurement's images, darks, flats and previous frames, wedge
// calibration, characterisation, `xgauge normalize` and `xgauge convert`,
// and the Python module all read through readRadiograph()
// (docs/formats.md, "Radiographs").
//
//   TIFF / BigTIFF   by its magic bytes; one page, or the mean of its pages
//                    (image/tiff.h)
//   NeXus NXtomo     by the HDF5 signature; `scan.nxs#dark` selects frames
//                    (image/nxtomo.h)
//   DICONDE          by 'DICM' after the 128-byte preamble (image/diconde.h)
//   raw + sidecar    any other file with `name.json` or `name.ini` beside it
//                    (image/raw_file.h)
//
// The format is chosen by the file's bytes, never by its name, so a
// misnamed file is still read as what it is. Every reader refuses hostile
// files as readTiff does (sizes checked against the file and the memory
// limit of tiff.h before allocating, NaN pixels named, errors naming the
// file) and returns pixels as float in the file's own units.
#pragma once

#include "xgauge/image/image.h"
#include "xgauge/image/tiff.h"

#include <filesystem>
#include <string>

namespace xgauge {

enum class RadiographFormat { kTiff, kRaw, kNxTomo, kDiconde };

// "TIFF", "raw", "NXtomo", "DICONDE".
const char* toString(RadiographFormat format);

struct RadiographFile {
  Image image;
  // How many frames were averaged into `image` (pages of a TIFF, frames of
  // a raw file, darks or flats of an NXtomo scan, frames of a DICOM file).
  // The noise xgauge assumes is estimated from the image itself (the
  // residuals' median absolute deviation, the neighbour differences over
  // the open beam), so a mean of N frames is weighed with the 1/sqrt(N)
  // lower noise it has without further use of this count; it is reported
  // so that a caller can state it.
  int frames = 1;
  RadiographFormat format = RadiographFormat::kTiff;
};

// Reads the radiograph at `path`, which for NXtomo may end in a frame
// selector (`scan.nxs#projection=3`; a file whose own name contains '#' is
// taken whole when it exists). `sha256`: the SHA-256 of the file's bytes
// (raw: of the raw file followed by its sidecar; NXtomo: of the whole file).
// `expected`: a size to insist on, checked before any pixel is decoded.
// Throws Error naming the file for a missing file, a folder, and whatever
// the format's reader refuses.
RadiographFile readRadiograph(const std::filesystem::path& path, std::string* sha256 = nullptr,
                              const ExpectedImageSize* expected = nullptr);

// The format a file name asks for when writing: .tif/.tiff TIFF, .raw raw +
// .raw.json sidecar, .nxs/.h5/.hdf5/.nx5 NXtomo (one projection), .dcm/.dicom
// DICONDE; throws Error naming the file for any other extension.
RadiographFormat writableFormatOf(const std::filesystem::path& path);

// Writes `image` in the format its name asks for (writableFormatOf), as
// 16-bit unsigned integers (rounded, clamped to 0..65535) or 32-bit floats
// (exact); atomically, as writeTiff.
void writeRadiograph(const std::filesystem::path& path, const Image& image, TiffFormat samples);

}  // namespace xgauge
