#include "xgauge/image/tiff.h"

#include "frames.h"
#include "xgauge/core/atomic_file.h"
#include "xgauge/core/digest.h"
#include "xgauge/core/error.h"
#include "xgauge/core/log.h"

#include <fcntl.h>
#include <tiffio.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

namespace xgauge {
namespace {

constexpr size_t kStripBytes = size_t{256} << 10;

// libtiff reports problems through handlers. The global ones
// (TIFFSetErrorHandler) are shared by every thread and print to stderr, so
// each open file gets its own (TIFFOpenOptions, libtiff >= 4.5) that collect
// the messages here. It must outlive the TIFF handle: closing may report too.
struct TiffMessages {
  std::string file;  // libtiff often passes the file name as the "module"
  std::string errors;
  std::vector<std::string> warnings;
};

std::string formatMessage(const TiffMessages& messages, const char* module, const char* format,
                          va_list args) {
  va_list copy;
  va_copy(copy, args);
  const int length = std::vsnprintf(nullptr, 0, format, copy);
  va_end(copy);
  std::string text;
  if (length > 0) {
    text.resize(static_cast<size_t>(length) + 1);
    std::vsnprintf(text.data(), text.size(), format, args);
    text.resize(static_cast<size_t>(length));
  }
  if (module != nullptr && *module != '\0' && messages.file != module)
    text = std::string(module) + ": " + text;
  return text;
}

int collectError(TIFF*, void* user_data, const char* module, const char* format, va_list args) {
  auto& messages = *static_cast<TiffMessages*>(user_data);
  if (!messages.errors.empty()) messages.errors += "; ";
  messages.errors += formatMessage(messages, module, format, args);
  return 1;  // handled: libtiff does not call the global handlers
}

int collectWarning(TIFF*, void* user_data, const char* module, const char* format, va_list args) {
  auto& messages = *static_cast<TiffMessages*>(user_data);
  messages.warnings.push_back(formatMessage(messages, module, format, args));
  return 1;
}

struct TiffCloser {
  void operator()(TIFF* tif) const { TIFFClose(tif); }
};
using TiffHandle = std::unique_ptr<TIFF, TiffCloser>;

using OpenOptions = std::unique_ptr<TIFFOpenOptions, decltype(&TIFFOpenOptionsFree)>;

OpenOptions openOptions(TiffMessages& messages) {
  OpenOptions options(TIFFOpenOptionsAlloc(), &TIFFOpenOptionsFree);
  XG_CHECK(options != nullptr, "out of memory");
  TIFFOpenOptionsSetErrorHandlerExtR(options.get(), collectError, &messages);
  TIFFOpenOptionsSetWarningHandlerExtR(options.get(), collectWarning, &messages);
  return options;
}

TiffHandle openTiff(const std::filesystem::path& path, const char* mode, TiffMessages& messages) {
  const OpenOptions options = openOptions(messages);
  return TiffHandle(TIFFOpenExt(path.c_str(), mode, options.get()));
}

// Opens `path` for reading once: when `sha256` is given, the file's bytes are
// hashed through the same descriptor before libtiff reads it, so the digest
// is of exactly the file that was decoded.
TiffHandle openTiffForReading(const std::filesystem::path& path, TiffMessages& messages,
                              std::string* sha256, const SourceLocation& where) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw Error(fmt::format("cannot open the file: {}", std::strerror(errno)), where);
  if (sha256) {
    Sha256 hash;
    std::vector<char> buffer(size_t{1} << 20);
    for (;;) {
      const ssize_t got = ::read(fd, buffer.data(), buffer.size());
      if (got < 0) {
        const int error = errno;
        ::close(fd);
        throw Error(fmt::format("cannot read the file: {}", std::strerror(error)), where);
      }
      if (got == 0) break;
      hash.update(buffer.data(), static_cast<size_t>(got));
    }
    *sha256 = hash.hex();
    if (::lseek(fd, 0, SEEK_SET) != 0) {
      ::close(fd);
      throw Error("cannot rewind the file", where);
    }
  }
  const OpenOptions options = openOptions(messages);
  TIFF* tif = TIFFFdOpenExt(fd, path.c_str(), "r", options.get());
  if (!tif) ::close(fd);  // TIFFClose closes it otherwise
  return TiffHandle(tif);
}

// " (libtiff: ...)" or nothing.
std::string libtiffSays(const TiffMessages& messages) {
  return messages.errors.empty() ? std::string() : " (libtiff: " + messages.errors + ")";
}

std::string describeSamples(uint16_t bits, uint16_t sample_format) {
  const char* kind = "unknown sample format";
  switch (sample_format) {
    case SAMPLEFORMAT_UINT:
      kind = "unsigned integer";
      break;
    case SAMPLEFORMAT_INT:
      kind = "signed integer";
      break;
    case SAMPLEFORMAT_IEEEFP:
      kind = "float";
      break;
    case SAMPLEFORMAT_VOID:
      kind = "untyped";
      break;
    case SAMPLEFORMAT_COMPLEXINT:
      kind = "complex integer";
      break;
    case SAMPLEFORMAT_COMPLEXIEEEFP:
      kind = "complex float";
      break;
    default:
      return fmt::format("{}-bit samples of unknown sample format {}", bits, sample_format);
  }
  return fmt::format("{}-bit {}", bits, kind);
}

std::string describePhotometric(uint16_t photometric) {
  switch (photometric) {
    case PHOTOMETRIC_MINISWHITE:
      return "MinIsWhite (inverted grey)";
    case PHOTOMETRIC_RGB:
      return "RGB";
    case PHOTOMETRIC_PALETTE:
      return "palette (indexed colour)";
    case PHOTOMETRIC_MASK:
      return "transparency mask";
    case PHOTOMETRIC_SEPARATED:
      return "separated (CMYK)";
    default:
      return fmt::format("{}", photometric);
  }
}

// Memory a file may make readTiff allocate (the image as floats, or one
// strip or tile buffer); setTiffMemoryLimit() changes it.
std::atomic<uint64_t> memory_limit{kDefaultTiffMemoryLimit};

using frames::mebibytes;

// How many bytes of decoded pixels one byte of compressed data can give at
// most. Deflate's
// limit is 1032:1 (RFC 1951: 258 bytes per 2-bit code at best); LZW emits at
// most 4096 bytes per 9-bit code; PackBits 128 bytes per 2.
//
// Other codecs (ZSTD, LZMA, JPEG, ...) can pack a constant image further, but
// a radiograph holds noise: no codec packs one 4096-fold, so that bound
// applies to them, and a file declaring more pixels than it can hold is
// refused before the image is allocated.
double maxExpansion(uint16_t compression) {
  switch (compression) {
    case COMPRESSION_NONE:
      return 1.0;
    case COMPRESSION_PACKBITS:
      return 64.0;
    case COMPRESSION_LZW:
      return 4096.0 * 8.0 / 9.0;
    case COMPRESSION_DEFLATE:
    case COMPRESSION_ADOBE_DEFLATE:
      return 1032.0;
    default:
      return 4096.0;
  }
}

// Refuses, before any pixel buffer exists, a file whose declared layout
// would need more memory than the limit, or more pixel data than the file
// can hold (a 200-byte file declaring 32768 x 32768 pixels).
void checkDeclaredSize(TIFF* tif, uint32_t width, uint32_t height, size_t sample_bytes,
                       uint64_t file_bytes, const TiffMessages& messages,
                       const SourceLocation& where) {
  const uint64_t limit = memory_limit.load();
  const uint64_t image_bytes = uint64_t{width} * height * sizeof(float);
  if (image_bytes > limit)
    failAt(where,
           "the file declares {}x{} pixels, {} as floats: more than the limit of {} "
           "(--max-image-mb)",
           width, height, mebibytes(image_bytes), mebibytes(limit));
  const bool tiled = TIFFIsTiled(tif) != 0;
  const tmsize_t block_bytes = tiled ? TIFFTileSize(tif) : TIFFStripSize(tif);
  if (block_bytes <= 0)
    failAt(where, "corrupt TIFF: invalid {} size{}", tiled ? "tile" : "strip",
           libtiffSays(messages));
  if (static_cast<uint64_t>(block_bytes) > limit)
    failAt(where, "the file declares {} of {} bytes: more than the limit of {} (--max-image-mb)",
           tiled ? "tiles" : "strips", block_bytes, mebibytes(limit));
  // Both are held at once while decoding.
  if (image_bytes + static_cast<uint64_t>(block_bytes) > limit)
    failAt(where,
           "the file declares {}x{} pixels in {} of {} bytes: the image and one {} need {}, more "
           "than the limit of {} (--max-image-mb)",
           width, height, tiled ? "tiles" : "strips", block_bytes, tiled ? "tile" : "strip",
           mebibytes(image_bytes + static_cast<uint64_t>(block_bytes)), mebibytes(limit));

  uint16_t compression = COMPRESSION_NONE;
  TIFFGetFieldDefaulted(tif, TIFFTAG_COMPRESSION, &compression);
  const double expansion = maxExpansion(compression);
  uint64_t stored = 0;
  const uint32_t blocks = tiled ? TIFFNumberOfTiles(tif) : TIFFNumberOfStrips(tif);
  for (uint32_t i = 0; i < blocks; ++i) {
    // The bytes of each block that lie inside the file.
    const uint64_t offset = TIFFGetStrileOffset(tif, i);
    if (offset < file_bytes) stored += std::min<uint64_t>(TIFFGetStrileByteCount(tif, i), file_bytes - offset);
  }
  const uint64_t needed = uint64_t{width} * height * sample_bytes;
  if (static_cast<double>(needed) > expansion * static_cast<double>(stored))
    failAt(where,
           "the file declares {}x{} pixels of {} bytes ({} bytes) but holds only {} bytes of "
           "pixel data: it is truncated or corrupt",
           width, height, sample_bytes, needed, stored);
}

// Decodes the current directory strip by strip (or tile by tile) straight
// into a float image, so no more than one block of raw samples is held at
// once. `frame_label` names the page in a bad pixel's message.
template <typename Sample>
Image readSamples(TIFF* tif, uint32_t width, uint32_t height, const TiffMessages& messages,
                  const SourceLocation& where, const std::string& frame_label) {
  const int w = static_cast<int>(width), h = static_cast<int>(height);
  Image image(w, h);
  frames::SampleConverter<Sample> converter;
  converter.frame_label = frame_label;
  const size_t row_bytes = size_t{width} * sizeof(Sample);
  if (TIFFIsTiled(tif)) {
    uint32_t tile_width = 0, tile_height = 0;
    TIFFGetField(tif, TIFFTAG_TILEWIDTH, &tile_width);
    TIFFGetField(tif, TIFFTAG_TILELENGTH, &tile_height);
    const tmsize_t tile_bytes = TIFFTileSize(tif);
    if (tile_width == 0 || tile_height == 0 || tile_bytes <= 0 ||
        static_cast<uint64_t>(tile_bytes) < uint64_t{tile_width} * tile_height * sizeof(Sample))
      failAt(where, "corrupt TIFF: invalid tile size {}x{}{}", tile_width, tile_height,
             libtiffSays(messages));
    std::vector<unsigned char> tile(static_cast<size_t>(tile_bytes));
    for (uint32_t tile_y = 0; tile_y < height; tile_y += tile_height) {
      for (uint32_t tile_x = 0; tile_x < width; tile_x += tile_width) {
        if (TIFFReadTile(tif, tile.data(), tile_x, tile_y, 0, 0) < 0)
          failAt(where, "cannot decode the tile at pixel ({}, {}){}", tile_x, tile_y,
                 libtiffSays(messages));
        // The part of the tile inside the image (edge tiles are padded).
        const uint32_t rows = std::min(tile_height, height - tile_y);
        const auto columns = static_cast<int>(std::min(tile_width, width - tile_x));
        for (uint32_t r = 0; r < rows; ++r) {
          const auto y = static_cast<int>(tile_y + r);
          converter.convert(tile.data() + size_t{r} * tile_width * sizeof(Sample),
                            image.row(y) + tile_x, columns, static_cast<int>(tile_x), y, w);
        }
      }
    }
  } else {
    uint32_t rows_per_strip = 0;
    TIFFGetFieldDefaulted(tif, TIFFTAG_ROWSPERSTRIP, &rows_per_strip);
    if (rows_per_strip == 0 || rows_per_strip > height) rows_per_strip = height;
    std::vector<unsigned char> strip(size_t{rows_per_strip} * row_bytes);
    for (uint32_t row = 0; row < height; row += rows_per_strip) {
      const uint32_t rows = std::min(rows_per_strip, height - row);
      const auto bytes = static_cast<tmsize_t>(size_t{rows} * row_bytes);
      if (TIFFReadEncodedStrip(tif, TIFFComputeStrip(tif, row, 0), strip.data(), bytes) != bytes)
        failAt(where, "cannot decode the strip starting at row {}{}", row, libtiffSays(messages));
      for (uint32_t r = 0; r < rows; ++r) {
        const auto y = static_cast<int>(row + r);
        converter.convert(strip.data() + size_t{r} * row_bytes, image.row(y), w, 0, y, w);
      }
    }
  }
  converter.check(where);
  return image;
}

}  // namespace

void setTiffMemoryLimit(uint64_t bytes) {
  if (bytes == 0) fail("the TIFF memory limit must be positive");
  memory_limit.store(bytes);
}

uint64_t tiffMemoryLimit() { return memory_limit.load(); }

namespace {

// What one page (directory) declares; every page of a file must declare the
// same.
struct PageLayout {
  uint32_t width = 0, height = 0;
  uint16_t bits = 1, sample_format = SAMPLEFORMAT_UINT;
  bool operator==(const PageLayout&) const = default;
};

// Reads and checks the current directory's layout; `page_label` ("" for the
// first page, " (page 3)" after) goes into the messages.
PageLayout readLayout(TIFF* tif, const TiffMessages& messages, const SourceLocation& where,
                      const std::string& page_label) {
  PageLayout layout;
  if (!TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &layout.width) ||
      !TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &layout.height))
    failAt(where, "corrupt TIFF{}: no image size{}", page_label, libtiffSays(messages));
  uint16_t samples_per_pixel = 1;
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &samples_per_pixel);
  TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &layout.bits);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLEFORMAT, &layout.sample_format);
  if (samples_per_pixel != 1)
    failAt(where,
           "{} samples per pixel{} (colour or extra channels); only single-channel (grey) "
           "radiographs are supported",
           samples_per_pixel, page_label);
  uint16_t photometric = PHOTOMETRIC_MINISBLACK;
  TIFFGetField(tif, TIFFTAG_PHOTOMETRIC, &photometric);
  if (photometric != PHOTOMETRIC_MINISBLACK)
    failAt(where, "unsupported photometric interpretation {}{}; only MinIsBlack grey is supported",
           describePhotometric(photometric), page_label);
  if (layout.width == 0 || layout.height == 0)
    failAt(where, "the image{} has zero size ({}x{})", page_label, layout.width, layout.height);
  if (layout.width > uint32_t{std::numeric_limits<int>::max()} ||
      layout.height > uint32_t{std::numeric_limits<int>::max()})
    failAt(where, "the file declares {}x{} pixels{}: too large", layout.width, layout.height,
           page_label);
  const bool supported =
      (layout.sample_format == SAMPLEFORMAT_UINT &&
       (layout.bits == 8 || layout.bits == 16 || layout.bits == 32)) ||
      (layout.sample_format == SAMPLEFORMAT_IEEEFP && (layout.bits == 32 || layout.bits == 64));
  if (!supported)
    failAt(where,
           "unsupported samples{}: {} (supported: 8-, 16- or 32-bit unsigned integer, 32- or "
           "64-bit float)",
           page_label, describeSamples(layout.bits, layout.sample_format));
  return layout;
}

Image readPage(TIFF* tif, const PageLayout& layout, const TiffMessages& messages,
               const SourceLocation& where, const std::string& frame_label) {
  const uint32_t w = layout.width, h = layout.height;
  if (layout.sample_format == SAMPLEFORMAT_UINT && layout.bits == 8)
    return readSamples<uint8_t>(tif, w, h, messages, where, frame_label);
  if (layout.sample_format == SAMPLEFORMAT_UINT && layout.bits == 16)
    return readSamples<uint16_t>(tif, w, h, messages, where, frame_label);
  if (layout.sample_format == SAMPLEFORMAT_UINT && layout.bits == 32)
    return readSamples<uint32_t>(tif, w, h, messages, where, frame_label);
  if (layout.sample_format == SAMPLEFORMAT_IEEEFP && layout.bits == 32)
    return readSamples<float>(tif, w, h, messages, where, frame_label);
  return readSamples<double>(tif, w, h, messages, where, frame_label);
}

}  // namespace

Image readTiff(const std::filesystem::path& path, std::string* sha256,
               const ExpectedImageSize* expected, int* frames_averaged) {
  const SourceLocation where = SourceLocation::inFile(path.string());
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    throw Error(ec ? "cannot access the file: " + ec.message() : "file does not exist", where);
  if (std::filesystem::is_directory(path, ec)) throw Error("is a folder, not a TIFF file", where);

  TiffMessages messages{path.string(), {}, {}};
  const TiffHandle tif = openTiffForReading(path, messages, sha256, where);
  if (!tif) failAt(where, "not a readable TIFF file{}", libtiffSays(messages));

  // Check the first page's layout before touching the pixels.
  const PageLayout first = readLayout(tif.get(), messages, where, "");
  if (expected &&
      (first.width != uint32_t(expected->width) || first.height != uint32_t(expected->height)))
    failAt(where, "is {}x{} pixels but {} is {}x{}", first.width, first.height, expected->what,
           expected->width, expected->height);
  std::error_code size_error;
  const uintmax_t file_size = std::filesystem::file_size(path, size_error);
  const uint64_t file_bytes = size_error ? std::numeric_limits<uint64_t>::max() : file_size;

  // Page after page: repeated frames of one size and type, averaged.
  frames::FrameMean mean;
  for (int page = 1;; ++page) {
    const std::string label = page == 1 ? "" : fmt::format(" (page {})", page);
    if (page > 1) {
      const PageLayout layout = readLayout(tif.get(), messages, where, label);
      if (!(layout == first))
        failAt(where,
               "page {} is {}x{} pixels of {} but page 1 is {}x{} of {}: the pages of a "
               "multi-page TIFF must be repeated frames of one size and sample type (they are "
               "averaged)",
               page, layout.width, layout.height,
               describeSamples(layout.bits, layout.sample_format), first.width, first.height,
               describeSamples(first.bits, first.sample_format));
    }
    checkDeclaredSize(tif.get(), first.width, first.height, first.bits / 8u, file_bytes, messages,
                      where);
    if (page > 1) {
      const tmsize_t block =
          TIFFIsTiled(tif.get()) ? TIFFTileSize(tif.get()) : TIFFStripSize(tif.get());
      frames::checkMemory(where, first.width, first.height, static_cast<uint64_t>(page),
                          static_cast<uint64_t>(std::max<tmsize_t>(block, 0)));
    }
    mean.add(readPage(
        tif.get(), first, messages, where,
        page == 1 && TIFFLastDirectory(tif.get()) ? "" : fmt::format(" of page {}", page)));
    if (TIFFLastDirectory(tif.get())) break;
    if (page == std::numeric_limits<int>::max() || !TIFFReadDirectory(tif.get()))
      failAt(where, "cannot read page {} of the multi-page TIFF{}", page + 1,
             libtiffSays(messages));
  }
  if (frames_averaged) *frames_averaged = mean.count();

  for (const std::string& warning : messages.warnings)
    spdlog::debug("{}: libtiff warning: {}", path.string(), warning);
  return mean.take();
}

void writeTiff(const std::filesystem::path& path, const Image& image, TiffFormat format) {
  const SourceLocation where = SourceLocation::inFile(path.string());
  if (image.empty()) throw Error("cannot write an empty image", where);
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x)
      if (!std::isfinite(image(x, y)))
        failAt(where, "cannot write pixel ({}, {}) = {}: TIFF radiographs hold finite values", x, y,
               image(x, y));

  const bool as_uint16 = format == TiffFormat::kUInt16;
  const size_t sample_bytes = as_uint16 ? sizeof(uint16_t) : sizeof(float);
  const auto width = static_cast<uint32_t>(image.width());
  const auto height = static_cast<uint32_t>(image.height());
  const size_t row_bytes = size_t{width} * sample_bytes;
  const uint32_t rows_per_strip =
      static_cast<uint32_t>(std::clamp<size_t>(kStripBytes / row_bytes, 1, height));
  // Classic TIFF addresses 4 GiB; leave room for the directory and for
  // deflate's worst case (a few bytes per 16 KiB block).
  const bool big_tiff = image.size() * sample_bytes > (uint64_t{1} << 32) - (uint64_t{1} << 26);

  AtomicFile file(path);
  {
    TiffMessages messages{file.tempPath().string(), {}, {}};
    const TiffHandle tif = openTiff(file.tempPath(), big_tiff ? "w8" : "w", messages);
    if (!tif) failAt(where, "cannot create the TIFF file{}", libtiffSays(messages));

    const auto set = [&](ttag_t tag, auto value) {
      if (TIFFSetField(tif.get(), tag, value) != 1)
        failAt(where, "cannot set TIFF tag {}{}", tag, libtiffSays(messages));
    };
    set(TIFFTAG_IMAGEWIDTH, width);
    set(TIFFTAG_IMAGELENGTH, height);
    set(TIFFTAG_SAMPLESPERPIXEL, 1);
    set(TIFFTAG_BITSPERSAMPLE, as_uint16 ? 16 : 32);
    set(TIFFTAG_SAMPLEFORMAT, as_uint16 ? SAMPLEFORMAT_UINT : SAMPLEFORMAT_IEEEFP);
    set(TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
    set(TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    set(TIFFTAG_COMPRESSION, COMPRESSION_ADOBE_DEFLATE);
    // Floats with the floating-point predictor (TIFF Technical Note 3, read
    // by libtiff, GDAL, tifffile and Bio-Formats) and zlib's fastest level:
    // a measurement's 4096^2 simulated radiograph took 25 MB and about a
    // second to write without the predictor at the default level, 5.3 MB
    // and a third of that with both.
    set(TIFFTAG_PREDICTOR, as_uint16 ? PREDICTOR_HORIZONTAL : PREDICTOR_FLOATINGPOINT);
    set(TIFFTAG_ZIPQUALITY, 1);
    set(TIFFTAG_ROWSPERSTRIP, rows_per_strip);
    set(TIFFTAG_SOFTWARE, "xgauge");

    // Convert strip by strip (the encoder may also modify its input buffer).
    std::vector<unsigned char> strip(size_t{rows_per_strip} * row_bytes);
    for (uint32_t row = 0; row < height; row += rows_per_strip) {
      const uint32_t rows = std::min(rows_per_strip, height - row);
      for (uint32_t r = 0; r < rows; ++r) {
        const float* in = image.row(static_cast<int>(row + r));
        unsigned char* out = strip.data() + size_t{r} * row_bytes;
        if (as_uint16) {
          for (uint32_t x = 0; x < width; ++x) {
            const auto value = static_cast<uint16_t>(
                std::lround(std::clamp(static_cast<double>(in[x]), 0.0, 65535.0)));
            std::memcpy(out + size_t{x} * sizeof(value), &value, sizeof(value));
          }
        } else {
          std::memcpy(out, in, row_bytes);
        }
      }
      const auto bytes = static_cast<tmsize_t>(size_t{rows} * row_bytes);
      if (TIFFWriteEncodedStrip(tif.get(), TIFFComputeStrip(tif.get(), row, 0), strip.data(),
                                bytes) != bytes)
        failAt(where, "cannot write the strip starting at row {}{}", row, libtiffSays(messages));
    }
    if (TIFFFlush(tif.get()) != 1)
      failAt(where, "cannot finish the TIFF file (disk full?){}", libtiffSays(messages));
  }
  file.commit();
}

}  // namespace xgauge
