// Raw radiographs with a sidecar: `name.raw` holds the samples, headerless
// or after `offset` bytes of someone else's header, and `name.raw.json` (or
// `name.raw.ini`, section [raw]) says how to read them (docs/formats.md,
// "Radiographs"):
//
//   width, height  pixels (required)
//   type           uint8 | uint16 | uint32 | float32 | float64 (required)
//   byte_order     little | big (required unless type is uint8)
//   offset         bytes before the first sample (default 0)
//   frames         frames stored one after the other, averaged (default 1)
//
// Samples are row-major, row 0 first (the top, docs/conventions.md), frames
// one after the other. The file must hold exactly offset + frames * width *
// height * bytes-per-sample bytes: a sidecar that does not describe the file
// is refused rather than read as garbage.
#pragma once

#include "xgauge/image/image.h"
#include "xgauge/image/tiff.h"

#include <filesystem>
#include <optional>
#include <string>

namespace xgauge {

enum class RawSampleType { kUInt8, kUInt16, kUInt32, kFloat32, kFloat64 };

// The sidecar of `raw` that exists: `raw` + ".json", else `raw` + ".ini";
// nullopt when neither does (both existing is refused by readRawRadiograph).
std::optional<std::filesystem::path> rawSidecarOf(const std::filesystem::path& raw);

// Reads `raw` as its sidecar describes; `frames_averaged` gets the frame
// count. Conversions as readTiff (uint32 exact up to 2^24, float64 rounded).
//
// With `sha256`: the SHA-256 of the raw file's bytes followed by the
// sidecar's bytes (what `cat name.raw name.raw.json | sha256sum` prints),
// both taken from the bytes this read parsed, so the digest changes when
// either file does.
//
// Throws Error naming the file (the sidecar with its key for sidecar
// problems: "name.raw.json: /type: ...", "name.raw.ini:3: unknown key
// 'widht'; did you mean 'width'?") for: a missing sidecar, both sidecars,
// a missing, misspelled or unknown key, a value out of range, a file length
// other than the sidecar declares (saying both), a declared size beyond the
// memory limit (tiff.h, checked before allocating), an image size other
// than `expected`, or a float sample that is NaN, infinite or beyond the
// float range (naming the pixel and, with several frames, the frame).
Image readRawRadiograph(const std::filesystem::path& raw, std::string* sha256 = nullptr,
                        const ExpectedImageSize* expected = nullptr,
                        int* frames_averaged = nullptr);

// Writes `image` as `raw` plus `raw`.json (one frame, little-endian, offset
// 0), kUInt16 rounded and clamped as writeTiff does, kFloat32 exactly. Both
// files are written to temporaries first and renamed into place, the raw
// file first; after an error neither remains. Throws Error for an empty
// image or a non-finite pixel (naming it), or a write failure.
void writeRawRadiograph(const std::filesystem::path& raw, const Image& image, TiffFormat format);

}  // namespace xgauge
