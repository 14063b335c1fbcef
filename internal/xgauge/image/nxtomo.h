// NeXus NXtomo files (HDF5, libhdf5's C API): a tomography scan's frames in
// one file, from which a radiograph is one frame, or the mean of the darks
// or of the flats (docs/formats.md, "Radiographs").
//
// Datasets read (NXtomo, NeXus application definition):
//   /entry/data/data                          frames x rows x columns samples
//                                             (NXtomo links it to
//                                             /entry/instrument/detector/data)
//   /entry/instrument/detector/image_key      one integer per frame: 0
//                                             projection, 1 flat, 2 dark,
//                                             3 invalid (never read)
//   /entry/sample/rotation_angle              one number per frame (read for
//                                             the angle= selector only)
// Samples: 8-, 16- or 32-bit unsigned integers or 32- or 64-bit floats, of
// either byte order, stored contiguously or in chunks with any filter
// libhdf5 decodes (converted as readTiff converts).
//
// The frame selector follows the path after a '#' (`scan.nxs#dark`):
//   projection=N   the N-th projection (image_key 0), counting from 0 in
//                  the file's order
//   angle=A        the projection whose rotation_angle is A (the file's
//                  unit, degrees in NXtomo practice) within 1e-6
//   dark, flat     the mean of every dark (image_key 2) or flat (1) frame
//   (none)         the file's only projection; refused when it has several
#pragma once

#include "xgauge/image/image.h"
#include "xgauge/image/tiff.h"

#include <filesystem>
#include <span>
#include <string>
#include <string_view>

namespace xgauge {

// Reads the frames `selector` names (see above; "" for none) from the
// NXtomo file `path`; `frames_averaged` gets how many were averaged.
//
// With `sha256`: the SHA-256 of the whole file's bytes, read before libhdf5
// opens it; the file's size, modification time and inode are compared
// before and after, and a file that changed in between is refused.
//
// Throws Error naming the file (and the selector or dataset): not an HDF5
// file, a missing dataset (naming it), a dataset of the wrong rank, type
// or length (image_key and rotation_angle: one value per frame), a
// selector that is malformed or selects nothing (saying what the file
// holds), a declared size beyond the memory limit (tiff.h) or beyond what
// the file stores (checked before reading), a size other than `expected`,
// a NaN or infinite float sample (naming pixel and frame), or any error
// libhdf5 reports (with its message). libhdf5 prints nothing.
//
// The file is read in a child process: libhdf5 1.10 can crash on a crafted
// file, and such a crash is thrown as this file's Error ("libhdf5 crashed
// reading the file").
Image readNxTomo(const std::filesystem::path& path, std::string_view selector,
                 std::string* sha256 = nullptr, const ExpectedImageSize* expected = nullptr,
                 int* frames_averaged = nullptr);

// The same in this process (`lock`: hold the library's libhdf5 lock): for
// the fuzz target, which looks for libhdf5's crashes too.
Image readNxTomoInProcess(const std::filesystem::path& path, std::string_view selector,
                          std::string* sha256, const ExpectedImageSize* expected,
                          int* frames_averaged, bool lock = true);

// One frame to write: the image, its image_key (0 projection, 1 flat,
// 2 dark) and its rotation angle in degrees.
struct NxTomoFrame {
  const Image* image = nullptr;
  int image_key = 0;
  double rotation_angle_deg = 0.0;
};

// Writes an NXtomo file holding `frames` (all of one size) in that order:
// /entry/instrument/detector/data (uint16 rounded and clamped as writeTiff
// does, or float32 exactly; contiguous, little-endian) linked from
// /entry/data/data, image_key, rotation_angle (units "degree") and the
// NX_class attributes; no time stamps, so the same frames give the same
// bytes. Atomic (AtomicFile). Throws Error for no frames, frames of
// different sizes, an empty image, a non-finite pixel or a write failure.
void writeNxTomo(const std::filesystem::path& path, std::span<const NxTomoFrame> frames,
                 TiffFormat format);

}  // namespace xgauge
