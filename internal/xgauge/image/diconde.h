// DICONDE radiographs (DICOM for NDE, ASTM E2339; DCMTK's dcmdata), as
// digital radiography cabinets export them (docs/formats.md, "Radiographs").
//
// Read: (0028,0002) Samples per Pixel = 1, (0028,0004) Photometric
// Interpretation MONOCHROME2, (0028,0010) Rows, (0028,0011) Columns,
// (0028,0100) Bits Allocated 8 or 16, (0028,0101) Bits Stored (the bits above
// it are masked off), (0028,0103) Pixel Representation 0 (unsigned),
// (0028,0008) Number of Frames (default 1; several are averaged),
// (0028,1053) Rescale Slope and (0028,1052) Rescale Intercept (value =
// slope * stored + intercept, in double, then rounded to float; default 1
// and 0), and (7FE0,0010) Pixel Data in a native (uncompressed) transfer
// syntax: implicit or explicit VR little-endian, or explicit big-endian
// (deflated and every compressed syntax are refused, naming them). Also (7FE0,0008) Float Pixel
// Data with Bits Allocated 32, which xgauge writes for float32 images (no rescale applies to it).
#pragma once

#include "xgauge/image/image.h"
#include "xgauge/image/tiff.h"

#include <filesystem>
#include <string>

namespace xgauge {

// Reads a DICOM file's one image (or the mean of its frames;
// `frames_averaged` says how many). The file is read into memory once (its
// size checked against the memory limit of tiff.h first), hashed when
// `sha256` is given, and parsed from those bytes. Before DCMTK parses them,
// every element header is walked and a value declared longer than the
// bytes left is refused: DCMTK would allocate the declared length first.
//
// Throws Error naming the file (and the tag) for: not a DICOM file, a
// transfer syntax other than the three native ones, naming it ("decompress
// it first, e.g. dcmdjpeg"), an element longer than the file, a missing or contradictory tag,
// colour or MONOCHROME1 images, signed or other bit depths, Pixel Data shorter than Rows x Columns
// x Frames, a size beyond the memory limit or other than `expected`, a rescale giving a non-finite
// value, a NaN float sample (naming pixel and frame), or any error DCMTK reports (with its
// message). DCMTK prints nothing.
Image readDiconde(const std::filesystem::path& path, std::string* sha256 = nullptr,
                  const ExpectedImageSize* expected = nullptr, int* frames_averaged = nullptr);

// Writes `image` as a DICOM file (explicit VR little-endian, with the file
// meta header): SOP class Digital X-Ray Image Storage - For Processing,
// modality DX, MONOCHROME2, one frame; kUInt16 as 16-bit unsigned Pixel Data
// (rounded and clamped as writeTiff does), kFloat32 as 32-bit Float Pixel
// Data (7FE0,0008), exact. The UIDs derive from the pixels' SHA-256 (root
// 2.25), so the same image gives the same bytes. Atomic (AtomicFile).
// Throws Error for an empty image, a non-finite pixel or a write failure.
void writeDiconde(const std::filesystem::path& path, const Image& image, TiffFormat format);

}  // namespace xgauge
