#include "xgauge/image/tiff.h"

#include "hand_made_tiff.h"
#include "test_folder.h"

#include <gtest/gtest.h>
#include <tiffio.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <thread>
#include <vector>

namespace xgauge {
namespace {

// How a test writes a TIFF with libtiff directly, to cover layouts that
// writeTiff never produces.
struct RawLayout {
  uint16_t bits = 8;
  uint16_t sample_format = SAMPLEFORMAT_UINT;
  uint16_t samples_per_pixel = 1;
  uint16_t photometric = PHOTOMETRIC_MINISBLACK;
  uint16_t compression = COMPRESSION_NONE;
  uint16_t predictor = PREDICTOR_NONE;
  uint32_t rows_per_strip = 0;  // 0: one strip
  uint32_t tile_size = 0;       // > 0: square tiles of this size instead of strips
  bool big_tiff = false;
};

// `data`: width * height * samples_per_pixel samples of bits / 8 bytes each,
// row-major, native byte order.
void writeRawTiff(const std::filesystem::path& path, uint32_t width, uint32_t height,
                  const RawLayout& layout, const std::vector<unsigned char>& data) {
  TIFF* tif = TIFFOpen(path.c_str(), layout.big_tiff ? "w8" : "w");
  ASSERT_NE(tif, nullptr);
  TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, width);
  TIFFSetField(tif, TIFFTAG_IMAGELENGTH, height);
  TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, layout.bits);
  TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, layout.sample_format);
  TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, layout.samples_per_pixel);
  TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, layout.photometric);
  TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
  TIFFSetField(tif, TIFFTAG_COMPRESSION, layout.compression);
  if (layout.predictor != PREDICTOR_NONE) TIFFSetField(tif, TIFFTAG_PREDICTOR, layout.predictor);
  const size_t pixel_bytes = size_t{layout.bits} / 8 * layout.samples_per_pixel;
  const size_t row_bytes = width * pixel_bytes;
  std::vector<unsigned char> buffer;
  if (layout.tile_size > 0) {
    const uint32_t t = layout.tile_size;
    TIFFSetField(tif, TIFFTAG_TILEWIDTH, t);
    TIFFSetField(tif, TIFFTAG_TILELENGTH, t);
    for (uint32_t ty = 0; ty < height; ty += t) {
      for (uint32_t tx = 0; tx < width; tx += t) {
        buffer.assign(size_t{t} * t * pixel_bytes, 0);  // edge tiles padded with 0
        for (uint32_t r = 0; r < t && ty + r < height; ++r)
          std::memcpy(buffer.data() + r * t * pixel_bytes,
                      data.data() + (ty + r) * row_bytes + tx * pixel_bytes,
                      std::min(t, width - tx) * pixel_bytes);
        ASSERT_GE(TIFFWriteTile(tif, buffer.data(), tx, ty, 0, 0), 0);
      }
    }
  } else {
    const uint32_t rows_per_strip = layout.rows_per_strip > 0 ? layout.rows_per_strip : height;
    TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, rows_per_strip);
    for (uint32_t row = 0; row < height; row += rows_per_strip) {
      const uint32_t rows = std::min(rows_per_strip, height - row);
      buffer.assign(data.begin() + static_cast<std::ptrdiff_t>(row * row_bytes),
                    data.begin() + static_cast<std::ptrdiff_t>((row + rows) * row_bytes));
      ASSERT_GE(TIFFWriteEncodedStrip(tif, TIFFComputeStrip(tif, row, 0), buffer.data(),
                                      static_cast<tmsize_t>(buffer.size())),
                0);
    }
  }
  TIFFClose(tif);
}

template <typename T>
std::vector<unsigned char> bytesOf(const std::vector<T>& values) {
  std::vector<unsigned char> bytes(values.size() * sizeof(T));
  std::memcpy(bytes.data(), values.data(), bytes.size());
  return bytes;
}

// A value per pixel that differs between neighbours, rows and columns.
double pattern(int x, int y) { return 1000.0 + 37.0 * x - 11.0 * y + 0.25 * ((x * y) % 7); }

std::string messageOf(const std::filesystem::path& path) {
  try {
    readTiff(path);
  } catch (const Error& e) {
    EXPECT_EQ(e.where().file, path.string());
    return e.what();
  }
  ADD_FAILURE() << "readTiff did not throw for " << path;
  return {};
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(Tiff, Float32RoundTripIsExact) {
  TestFolder folder;
  // Several strips (about 256 KiB each), negative values, tiny and huge values.
  Image image(301, 517);
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x)
      image(x, y) = static_cast<float>(std::sin(0.1 * x) * std::exp(0.05 * (y % 40)) - 0.5);
  image(0, 0) = std::numeric_limits<float>::denorm_min();
  image(1, 0) = std::numeric_limits<float>::max();
  image(2, 0) = -std::numeric_limits<float>::max();
  const auto path = folder / "float.tif";
  writeTiff(path, image, TiffFormat::kFloat32);
  const Image read = readTiff(path);
  ASSERT_EQ(read.width(), image.width());
  ASSERT_EQ(read.height(), image.height());
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x) ASSERT_EQ(read(x, y), image(x, y)) << x << ", " << y;
  EXPECT_EQ(folder.entries(), std::vector<std::string>{"float.tif"});
}

TEST(Tiff, UInt16RoundTripRoundsAndClamps) {
  TestFolder folder;
  Image image(700, 400);  // 1400-byte rows: several strips
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x)
      image(x, y) = static_cast<float>((x * 97 + y * 13) % 65536);
  image(0, 0) = -5.0f;     // clamped to 0
  image(1, 0) = 70000.0f;  // clamped to 65535
  image(2, 0) = 1.5f;      // halves round away from zero
  image(3, 0) = 2.4999f;
  image(4, 0) = 65535.4f;
  const auto path = folder / "adu.tif";
  writeTiff(path, image, TiffFormat::kUInt16);
  const Image read = readTiff(path);
  ASSERT_EQ(read.width(), 700);
  ASSERT_EQ(read.height(), 400);
  EXPECT_EQ(read(0, 0), 0.0f);
  EXPECT_EQ(read(1, 0), 65535.0f);
  EXPECT_EQ(read(2, 0), 2.0f);
  EXPECT_EQ(read(3, 0), 2.0f);
  EXPECT_EQ(read(4, 0), 65535.0f);
  for (int y = 1; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x) ASSERT_EQ(read(x, y), image(x, y)) << x << ", " << y;
}

TEST(Tiff, WritesSixteenBitDeflateStrips) {
  TestFolder folder;
  const auto path = folder / "adu.tif";
  writeTiff(path, Image(1000, 300, 7.0f), TiffFormat::kUInt16);
  TIFF* tif = TIFFOpen(path.c_str(), "r");
  ASSERT_NE(tif, nullptr);
  uint16_t bits = 0, compression = 0, predictor = 0, format = 0;
  uint32_t rows_per_strip = 0;
  TIFFGetField(tif, TIFFTAG_BITSPERSAMPLE, &bits);
  TIFFGetField(tif, TIFFTAG_COMPRESSION, &compression);
  TIFFGetField(tif, TIFFTAG_PREDICTOR, &predictor);
  TIFFGetField(tif, TIFFTAG_SAMPLEFORMAT, &format);
  TIFFGetField(tif, TIFFTAG_ROWSPERSTRIP, &rows_per_strip);
  EXPECT_EQ(bits, 16);
  EXPECT_EQ(format, SAMPLEFORMAT_UINT);
  EXPECT_EQ(compression, COMPRESSION_ADOBE_DEFLATE);
  EXPECT_EQ(predictor, PREDICTOR_HORIZONTAL);
  EXPECT_EQ(rows_per_strip, 131u);  // 256 KiB / 2000-byte rows
  EXPECT_EQ(TIFFNumberOfStrips(tif), 3u);
  TIFFClose(tif);
}

TEST(Tiff, WriteIsDeterministic) {
  TestFolder folder;
  Image image(64, 48);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) image(x, y) = static_cast<float>(pattern(x, y));
  const auto read_bytes = [](const std::filesystem::path& p) {
    std::string bytes(std::filesystem::file_size(p), '\0');
    std::ifstream(p, std::ios::binary)
        .read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return bytes;
  };
  writeTiff(folder / "a.tif", image, TiffFormat::kFloat32);
  writeTiff(folder / "b.tif", image, TiffFormat::kFloat32);
  EXPECT_EQ(read_bytes(folder / "a.tif"), read_bytes(folder / "b.tif"));
}

TEST(Tiff, ReadsEightBitStrips) {
  TestFolder folder;
  const uint32_t width = 13, height = 11;  // partial last strip
  std::vector<uint8_t> values(width * height);
  for (size_t i = 0; i < values.size(); ++i) values[i] = static_cast<uint8_t>((i * 29) % 256);
  RawLayout layout;
  layout.rows_per_strip = 4;
  const auto path = folder / "eight.tif";
  writeRawTiff(path, width, height, layout, bytesOf(values));
  const Image image = readTiff(path);
  ASSERT_EQ(image.width(), 13);
  ASSERT_EQ(image.height(), 11);
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x)
      ASSERT_EQ(image(static_cast<int>(x), static_cast<int>(y)),
                static_cast<float>(values[y * width + x]));
}

TEST(Tiff, ReadsTiledSixteenBitWithPartialTiles) {
  TestFolder folder;
  const uint32_t width = 40, height = 24;  // 16x16 tiles: edge tiles padded
  std::vector<uint16_t> values(width * height);
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x)
      values[y * width + x] = static_cast<uint16_t>(65535 - 1601 * x - y);
  RawLayout layout;
  layout.bits = 16;
  layout.tile_size = 16;
  const auto path = folder / "tiled.tif";
  writeRawTiff(path, width, height, layout, bytesOf(values));
  const Image image = readTiff(path);
  ASSERT_EQ(image.width(), 40);
  ASSERT_EQ(image.height(), 24);
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x)
      ASSERT_EQ(image(static_cast<int>(x), static_cast<int>(y)),
                static_cast<float>(values[y * width + x]))
          << x << ", " << y;
}

TEST(Tiff, ReadsCompressedFiles) {
  TestFolder folder;
  const uint32_t width = 50, height = 30;
  struct Case {
    const char* name;
    uint16_t compression;
    uint16_t predictor;
    uint32_t tile_size;
  };
  const Case cases[] = {
      {"lzw_predictor", COMPRESSION_LZW, PREDICTOR_HORIZONTAL, 0},
      {"deflate_fp_predictor_tiled", COMPRESSION_ADOBE_DEFLATE, PREDICTOR_FLOATINGPOINT, 16},
      {"packbits", COMPRESSION_PACKBITS, PREDICTOR_NONE, 0},
      {"zstd", COMPRESSION_ZSTD, PREDICTOR_NONE, 0}};
  std::vector<float> values(width * height);
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x)
      values[y * width + x] = static_cast<float>(pattern(static_cast<int>(x), static_cast<int>(y)));
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    if (!TIFFIsCODECConfigured(c.compression)) continue;
    RawLayout layout;
    layout.bits = 32;
    layout.sample_format = SAMPLEFORMAT_IEEEFP;
    layout.compression = c.compression;
    layout.predictor = c.predictor;
    layout.tile_size = c.tile_size;
    layout.rows_per_strip = 7;
    const auto path = folder / (std::string(c.name) + ".tif");
    writeRawTiff(path, width, height, layout, bytesOf(values));
    const Image image = readTiff(path);
    ASSERT_EQ(image.width(), 50);
    ASSERT_EQ(image.height(), 30);
    for (uint32_t i = 0; i < values.size(); ++i) ASSERT_EQ(image.pixels()[i], values[i]) << i;
  }
  EXPECT_TRUE(TIFFIsCODECConfigured(COMPRESSION_LZW));
  EXPECT_TRUE(TIFFIsCODECConfigured(COMPRESSION_ADOBE_DEFLATE));
}

TEST(Tiff, ReadsThirtyTwoBitUnsignedAndDoubleAndBigTiff) {
  TestFolder folder;
  {
    // Exact up to 2^24, rounded to the nearest float above.
    const std::vector<uint32_t> values = {0, 1, 16777216, 16777217, 4294967295u, 123456};
    RawLayout layout;
    layout.bits = 32;
    writeRawTiff(folder / "u32.tif", 3, 2, layout, bytesOf(values));
    const Image image = readTiff(folder / "u32.tif");
    EXPECT_EQ(image(0, 0), 0.0f);
    EXPECT_EQ(image(1, 0), 1.0f);
    EXPECT_EQ(image(2, 0), 16777216.0f);
    EXPECT_EQ(image(0, 1), 16777216.0f);  // 2^24 + 1 rounds to even
    EXPECT_EQ(image(1, 1), 4294967296.0f);
    EXPECT_EQ(image(2, 1), 123456.0f);
  }
  {
    const std::vector<double> values = {0.1, -2.5, 1e30, 0.75};
    RawLayout layout;
    layout.bits = 64;
    layout.sample_format = SAMPLEFORMAT_IEEEFP;
    layout.big_tiff = true;
    writeRawTiff(folder / "f64.tif", 2, 2, layout, bytesOf(values));
    const Image image = readTiff(folder / "f64.tif");
    EXPECT_EQ(image(0, 0), 0.1f);
    EXPECT_EQ(image(1, 0), -2.5f);
    EXPECT_EQ(image(0, 1), 1e30f);
    EXPECT_EQ(image(1, 1), 0.75f);
  }
}

TEST(Tiff, MissingFile) {
  TestFolder folder;
  EXPECT_TRUE(contains(messageOf(folder / "nothing.tif"), "does not exist"));
}

TEST(Tiff, TextFileIsNotATiffAndNothingGoesToStderr) {
  TestFolder folder;
  const auto path = folder / "notes.tif";
  std::ofstream(path) << "hello, this is not an image\n";
  ::testing::internal::CaptureStderr();
  const std::string message = messageOf(path);
  const std::string printed = ::testing::internal::GetCapturedStderr();
  EXPECT_TRUE(contains(message, "not a readable TIFF")) << message;
  EXPECT_TRUE(contains(message, "Not a TIFF")) << message;  // libtiff's own words
  EXPECT_EQ(printed, "");
}

TEST(Tiff, TruncatedFileIsCorrupt) {
  TestFolder folder;
  Image image(200, 100);
  for (int y = 0; y < 100; ++y)
    for (int x = 0; x < 200; ++x) image(x, y) = static_cast<float>(pattern(x, y));
  const auto path = folder / "cut.tif";
  writeTiff(path, image, TiffFormat::kFloat32);
  // Keep the header but cut the pixel data short; the directory (written at
  // the end by libtiff) goes with it.
  std::filesystem::resize_file(path, std::filesystem::file_size(path) / 2);
  ::testing::internal::CaptureStderr();
  const std::string message = messageOf(path);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_TRUE(contains(message, "libtiff")) << message;

  // Intact directory, garbage in the compressed data of the first strip
  // (libtiff puts the pixel data right after the 8-byte header).
  writeTiff(path, image, TiffFormat::kFloat32);
  {
    std::fstream file(path, std::ios::binary | std::ios::in | std::ios::out);
    file.seekp(12);
    const std::string garbage(200, '\xff');
    file.write(garbage.data(), static_cast<std::streamsize>(garbage.size()));
  }
  ::testing::internal::CaptureStderr();
  const std::string garbled = messageOf(path);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_TRUE(contains(garbled, "cannot decode the strip starting at row 0 (libtiff:")) << garbled;
}

TEST(Tiff, ZeroSizeIsRejected) {
  // A hand-made little-endian TIFF whose ImageWidth is 0 (libtiff refuses
  // to write one).
  TestFolder folder;
  const auto path = folder / "zero.tif";
  testing::writeDeclaredStripTiff(path, 0, 4, 8, 1, 1, 0, 256);
  ::testing::internal::CaptureStderr();
  const std::string message = messageOf(path);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_TRUE(contains(message, "zero") || contains(message, "Zero")) << message;
}

// Declared sizes are checked before any pixel buffer exists: these files
// used to make readTiff allocate 2 GiB, 8 GiB and a 35 GB tile buffer.
TEST(Tiff, HostileSizesAreRefusedBeforeAllocating) {
  TestFolder folder;
  const auto huge16 = folder / "huge16.tif", huge64 = folder / "huge64.tif";
  testing::writeDeclaredStripTiff(huge16, 32768, 32768, 16, 1, 1, 100, 198);
  testing::writeDeclaredStripTiff(huge64, 32768, 32768, 64, 3, 1, 100, 198);
  for (const auto& path : {huge16, huge64}) {
    const std::string message = messageOf(path);
    EXPECT_TRUE(contains(message, "declares 32768x32768 pixels, 4096 MiB as floats: more than the "
                                  "limit of 1088 MiB"))
        << message;
  }
  const auto tile = folder / "tile.tif";
  testing::writeDeclaredTileTiff(tile, 1090519056, 300);
  const std::string tile_message = messageOf(tile);
  EXPECT_TRUE(contains(tile_message, "tiles of 17448304896 bytes: more than the limit"))
      << tile_message;
}

TEST(Tiff, DeclaredSizeMustFitTheFile) {
  // Under the memory limit, but 256 bytes cannot hold 4096 x 4096 16-bit
  // pixels, neither raw nor deflated (at most 1032:1).
  TestFolder folder;
  const auto raw = folder / "raw.tif", deflated = folder / "deflated.tif";
  testing::writeDeclaredStripTiff(raw, 4096, 4096, 16, 1, 1, 56, 256);
  testing::writeDeclaredStripTiff(deflated, 4096, 4096, 16, 1, 8, 56, 256);
  for (const auto& path : {raw, deflated}) {
    const std::string message = messageOf(path);
    EXPECT_TRUE(contains(message, "declares 4096x4096 pixels of 2 bytes (33554432 bytes) but "
                                  "holds only 56 bytes of pixel data"))
        << path << ": " << message;
  }
}

TEST(Tiff, CodecsWithoutAKnownBoundStillNeedTheBytes) {
  // Found by fuzzing: a 402-byte ZSTD (50000) or JPEG (7) file declaring
  // 16384 x 16384 pixels made readTiff allocate 1 GiB before decoding (the
  // 8192 x 8192 here is within the memory limit).
  TestFolder folder;
  for (const uint16_t codec : {uint16_t{50000}, uint16_t{7}}) {
    const auto path = folder / fmt::format("codec{}.tif", codec);
    testing::writeDeclaredStripTiff(path, 8192, 8192, 8, 1, codec, 202, 402);
    const std::string message = messageOf(path);
    EXPECT_TRUE(contains(message, "but holds only 202 bytes of pixel data")) << message;
  }
}

TEST(Tiff, ExpectedSizeIsCheckedBeforeDecoding) {
  // A measurement knows its detector: another size is refused from the
  // header alone (this file could not even be decoded).
  TestFolder folder;
  const auto path = folder / "big.tif";
  testing::writeDeclaredStripTiff(path, 4096, 4096, 16, 1, 1, 56, 256);
  const ExpectedImageSize detector{128, 96, "the machine's detector"};
  try {
    readTiff(path, nullptr, &detector);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.message(), "is 4096x4096 pixels but the machine's detector is 128x96");
  }
  writeTiff(path, Image(128, 96, 0.5f), TiffFormat::kFloat32);
  EXPECT_EQ(readTiff(path, nullptr, &detector).width(), 128);
}

TEST(Tiff, MemoryLimitIsConfigurable) {
  TestFolder folder;
  const auto path = folder / "ok.tif";
  writeTiff(path, Image(100, 100, 0.5f), TiffFormat::kFloat32);
  const uint64_t before = tiffMemoryLimit();
  setTiffMemoryLimit(100 * 100 * 4 - 1);
  const std::string message = messageOf(path);
  setTiffMemoryLimit(before);
  EXPECT_TRUE(contains(message, "declares 100x100 pixels")) << message;
  EXPECT_EQ(readTiff(path).width(), 100);
  EXPECT_THROW(setTiffMemoryLimit(0), Error);
}

TEST(Tiff, MultiPageFileIsTheMeanOfItsPages) {
  TestFolder folder;
  const auto path = folder / "pages.tif";
  TIFF* tif = TIFFOpen(path.c_str(), "w");
  ASSERT_NE(tif, nullptr);
  std::vector<unsigned char> row(8, 7);
  for (int page = 0; page < 2; ++page) {
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, 8);
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, 1);
    TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, 8);
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, 1);
    TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
    TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, 1);
    ASSERT_EQ(TIFFWriteScanline(tif, row.data(), 0, 0), 1);
    ASSERT_EQ(TIFFWriteDirectory(tif), 1);
  }
  TIFFClose(tif);
  int frames = 0;
  const Image image = readTiff(path, nullptr, nullptr, &frames);
  EXPECT_EQ(frames, 2);
  EXPECT_EQ(image(7, 0), 7.0f);
}

TEST(Tiff, ErrorsFromSeveralThreadsStayApart) {
  // libtiff's global handlers would mix up messages of files read at once;
  // each file's handler collects its own.
  TestFolder folder;
  constexpr int kThreads = 8;
  for (int i = 0; i < kThreads; ++i)
    std::ofstream(folder / fmt::format("bad{}.tif", i))
        << std::string(static_cast<size_t>(i + 8), 'x');
  std::vector<std::string> messages(kThreads);
  std::vector<std::thread> threads;
  for (int i = 0; i < kThreads; ++i) {
    threads.emplace_back([&, i] {
      for (int repeat = 0; repeat < 50; ++repeat) {
        try {
          readTiff(folder / fmt::format("bad{}.tif", i));
        } catch (const Error& e) {
          messages[static_cast<size_t>(i)] = e.what();
        }
      }
    });
  }
  for (auto& thread : threads) thread.join();
  for (int i = 0; i < kThreads; ++i) {
    const std::string& message = messages[static_cast<size_t>(i)];
    EXPECT_TRUE(contains(message, fmt::format("bad{}.tif", i))) << message;
    EXPECT_TRUE(contains(message, "Not a TIFF")) << message;
    // Exactly one libtiff message: nothing from another thread's file.
    EXPECT_EQ(message.find(';'), std::string::npos) << message;
  }
}

TEST(Tiff, RgbIsRejected) {
  TestFolder folder;
  RawLayout layout;
  layout.samples_per_pixel = 3;
  layout.photometric = PHOTOMETRIC_RGB;
  writeRawTiff(folder / "rgb.tif", 4, 3, layout, std::vector<unsigned char>(4 * 3 * 3, 100));
  const std::string message = messageOf(folder / "rgb.tif");
  EXPECT_TRUE(contains(message, "3 samples per pixel")) << message;
}

TEST(Tiff, NanPixelIsNamed) {
  TestFolder folder;
  std::vector<float> values(5 * 4, 1.0f);
  values[2 * 5 + 3] = std::numeric_limits<float>::quiet_NaN();  // (3, 2)
  values[3 * 5 + 1] = std::numeric_limits<float>::infinity();   // later in row-major order
  RawLayout layout;
  layout.bits = 32;
  layout.sample_format = SAMPLEFORMAT_IEEEFP;
  writeRawTiff(folder / "nan.tif", 5, 4, layout, bytesOf(values));
  const std::string message = messageOf(folder / "nan.tif");
  EXPECT_TRUE(contains(message, "pixel (3, 2) is nan")) << message;
}

TEST(Tiff, InfinitePixelIsNamed) {
  TestFolder folder;
  std::vector<double> values(3 * 2, 0.5);
  values[1 * 3 + 2] = -std::numeric_limits<double>::infinity();
  RawLayout layout;
  layout.bits = 64;
  layout.sample_format = SAMPLEFORMAT_IEEEFP;
  writeRawTiff(folder / "inf.tif", 3, 2, layout, bytesOf(values));
  const std::string message = messageOf(folder / "inf.tif");
  EXPECT_TRUE(contains(message, "pixel (2, 1) is -inf")) << message;
  values[1 * 3 + 2] = 1e300;  // finite, but not as a float
  writeRawTiff(folder / "big.tif", 3, 2, layout, bytesOf(values));
  EXPECT_TRUE(contains(messageOf(folder / "big.tif"), "(2, 1)"));
}

TEST(Tiff, UnsupportedSampleFormatsAreNamed) {
  TestFolder folder;
  RawLayout layout;
  layout.bits = 32;
  layout.sample_format = SAMPLEFORMAT_INT;
  writeRawTiff(folder / "int32.tif", 2, 2, layout, std::vector<unsigned char>(16, 0));
  std::string message = messageOf(folder / "int32.tif");
  EXPECT_TRUE(contains(message, "32-bit signed integer")) << message;

  layout.bits = 16;
  layout.sample_format = SAMPLEFORMAT_IEEEFP;  // half float
  writeRawTiff(folder / "half.tif", 2, 2, layout, std::vector<unsigned char>(8, 0));
  message = messageOf(folder / "half.tif");
  EXPECT_TRUE(contains(message, "16-bit float")) << message;
}

TEST(Tiff, PaletteAndInvertedGreyAreRejected) {
  TestFolder folder;
  RawLayout layout;
  layout.photometric = PHOTOMETRIC_MINISWHITE;
  writeRawTiff(folder / "white.tif", 2, 2, layout, std::vector<unsigned char>(4, 0));
  const std::string message = messageOf(folder / "white.tif");
  EXPECT_TRUE(contains(message, "MinIsWhite")) << message;
}

TEST(Tiff, WriteErrorsLeaveNoFile) {
  TestFolder folder;
  Image image(4, 3, 1.0f);
  image(1, 2) = std::numeric_limits<float>::quiet_NaN();
  try {
    writeTiff(folder / "nan.tif", image, TiffFormat::kFloat32);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.where().file, (folder / "nan.tif").string());
    EXPECT_TRUE(contains(e.what(), "(1, 2)")) << e.what();
  }
  EXPECT_THROW(writeTiff(folder / "empty.tif", Image(), TiffFormat::kUInt16), Error);
  EXPECT_THROW(writeTiff(folder / "no_such_folder" / "a.tif", Image(2, 2), TiffFormat::kUInt16),
               Error);
  EXPECT_TRUE(folder.entries().empty());
}

TEST(Tiff, OverwritesAtomically) {
  TestFolder folder;
  const auto path = folder / "out.tif";
  writeTiff(path, Image(3, 3, 1.0f), TiffFormat::kFloat32);
  writeTiff(path, Image(5, 2, 2.0f), TiffFormat::kFloat32);
  const Image read = readTiff(path);
  EXPECT_EQ(read.width(), 5);
  EXPECT_EQ(read(4, 1), 2.0f);
  EXPECT_EQ(folder.entries(), std::vector<std::string>{"out.tif"});
}

}  // namespace
}  // namespace xgauge
