// Reading and writing single-channel TIFF radiographs (libtiff).
//
// Pixel values are returned and accepted as float in the file's own units
// (detector ADU for raw images, 1.0 = unattenuated for normalized ones); no
// scaling happens here. Row 0 is the first row stored in the file, which is
// the top of the image (docs/conventions.md); the Orientation tag is not applied.
//
// Every problem with a file throws xgauge::Error whose location names the
// file. libtiff's own messages are collected per open file (TIFFOpenExt) and
// appended to the error; nothing is printed to stderr, and reading or
// writing different files from several threads at once is safe.
#pragma once

#include "xgauge/image/image.h"

#include <cstdint>
#include <filesystem>
#include <string>

namespace xgauge {

// Reads a TIFF or BigTIFF file: its one image (directory), or the mean of
// its pages when it holds several (repeated frames of one detector, all of
// the same size and sample type; `frames_averaged` says how many). One page
// is returned exactly as converted below; several are summed in double and
// divided once (image/radiograph_file.h reads every radiograph format).
//
// Accepted: SamplesPerPixel 1, photometric MinIsBlack (or the tag absent), and
// samples that are 8-, 16- or 32-bit unsigned integers or 32- or 64-bit IEEE
// floats; stored in strips or tiles, with any compression and predictor
// libtiff decodes. 8- and 16-bit integers (so 16-bit ADU 0..65535) and 32-bit
// floats convert exactly; 32-bit integers are exact up to 2^24 and rounded to
// the nearest float above; 64-bit floats are rounded to the nearest float.
//
// Throws Error (naming the file) when the file is missing, not a TIFF or
// corrupt (with libtiff's message), has more than one sample per pixel, an
// unsupported bit depth or sample format (saying which), another photometric
// interpretation (palette, MinIsWhite, ...), pages of different sizes or
// sample types (naming the page), zero size, a declared size beyond the
// memory limit below or beyond what the file's bytes can hold (checked
// before any pixel buffer is allocated, page by page), or a float pixel that
// is NaN, infinite or beyond the float range (naming the first such pixel
// "(x, y)" in row-major order, and its page in a multi-page file).
// With `sha256`, also the SHA-256 of the file's bytes (core/digest.h), read
// through the same open file.
// With `expected`, a file declaring another size is refused before any
// pixel is decoded ("is WxH pixels but <what> is CxR").
struct ExpectedImageSize {
  int width = 0, height = 0;
  std::string what;  // e.g. "the machine's detector"
};
Image readTiff(const std::filesystem::path& path, std::string* sha256 = nullptr,
               const ExpectedImageSize* expected = nullptr, int* frames_averaged = nullptr);

// The most memory one read of a radiograph file may allocate, by any reader
// (TIFF, raw, NXtomo, DICONDE): the image as 32-bit floats plus the
// reader's buffer (one strip or tile, one frame of stored samples), held
// together while decoding; averaging several frames also holds the previous
// frame and a sum in double (16 bytes a pixel in all). The default is what a
// 16384 x 16384 radiograph needs with strips or tiles of up to 64 MiB
// (1088 MiB); the CLI sets it with --max-image-mb.
inline constexpr uint64_t kDefaultTiffMemoryLimit =
    uint64_t{16384} * 16384 * sizeof(float) + (uint64_t{64} << 20);
void setTiffMemoryLimit(uint64_t bytes);
uint64_t tiffMemoryLimit();

enum class TiffFormat {
  kUInt16,   // values rounded to the nearest integer (halves away from zero) and
             // clamped to [0, 65535]; the caller scales beforehand
  kFloat32,  // values stored exactly
};

// Writes `image` as a single-channel TIFF: deflate (zlib) compression, with the
// horizontal-differencing predictor for kUInt16 (lossless and read by every
// TIFF reader; the floating-point predictor is left out because several
// readers cannot decode it), strips of about 256 KiB, photometric
// MinIsBlack, Software "xgauge" and no time stamp, so the same image always
// gives the same bytes. BigTIFF only when a classic TIFF could exceed 4 GiB.
//
// The file is written atomically (AtomicFile): a reader never sees a partial
// file, and after an error no output file (and no temporary) remains.
// Throws Error (naming the file) for an empty image, a NaN or infinite pixel
// (naming it: readTiff would refuse the file), a missing output folder, or
// any write failure.
void writeTiff(const std::filesystem::path& path, const Image& image, TiffFormat format);

}  // namespace xgauge
