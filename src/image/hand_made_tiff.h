// Test helper: classic little-endian TIFF files written byte by byte, for
// layouts libtiff refuses to write (zero or absurd sizes, huge tiles).
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <utility>
#include <vector>

namespace xgauge::testing {

struct TiffEntry {
  uint16_t tag;
  uint16_t type;  // 3 = SHORT, 4 = LONG
  uint32_t value;
};

// One directory right after the header, no next directory; the file is
// padded with zeros to `file_bytes`.
inline void writeHandMadeTiff(const std::filesystem::path& path, const std::vector<TiffEntry>& entries,
                              size_t file_bytes) {
  std::vector<unsigned char> bytes = {'I', 'I', 42, 0, 8, 0, 0, 0};
  const auto u16 = [&](unsigned v) {
    bytes.push_back(static_cast<unsigned char>(v & 0xff));
    bytes.push_back(static_cast<unsigned char>((v >> 8) & 0xff));
  };
  const auto u32 = [&](uint32_t v) {
    u16(v & 0xffff);
    u16(v >> 16);
  };
  u16(static_cast<unsigned>(entries.size()));
  for (const TiffEntry& e : entries) {
    u16(e.tag);
    u16(e.type);
    u32(1);
    if (e.type == 3) {
      u16(e.value);
      u16(0);
    } else {
      u32(e.value);
    }
  }
  u32(0);  // no next directory
  if (bytes.size() < file_bytes) bytes.resize(file_bytes, 0);
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

// A greyscale strip image of `width` x `height` samples of `bits` bits
// (sample format 1 = unsigned, 3 = float) in one strip of `strip_bytes`
// bytes at offset 200, compression 1 (none) or 8 (deflate).
inline void writeDeclaredStripTiff(const std::filesystem::path& path, uint32_t width,
                                   uint32_t height, uint16_t bits, uint16_t sample_format,
                                   uint16_t compression, uint32_t strip_bytes, size_t file_bytes) {
  writeHandMadeTiff(path,
                    {{256, 4, width},
                     {257, 4, height},
                     {258, 3, bits},
                     {259, 3, compression},
                     {262, 3, 1},
                     {273, 4, 200},
                     {278, 4, height},
                     {279, 4, strip_bytes},
                     {339, 3, sample_format}},
                    file_bytes);
}

// A 32 x 32 8-bit image in tiles of `tile_width` x 16 declared at offset 200.
inline void writeDeclaredTileTiff(const std::filesystem::path& path, uint32_t tile_width,
                                  size_t file_bytes) {
  writeHandMadeTiff(path,
                    {{256, 4, 32},
                     {257, 4, 32},
                     {258, 3, 8},
                     {259, 3, 1},
                     {262, 3, 1},
                     {322, 4, tile_width},
                     {323, 4, 16},
                     {324, 4, 200},
                     {325, 4, 64}},
                    file_bytes);
}

}  // namespace xgauge::testing
