#include "xgauge/image/diconde.h"

#include "frames.h"
#include "xgauge/core/atomic_file.h"
#include "xgauge/core/digest.h"
#include "xgauge/core/error.h"

#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcistrmb.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmdata/dcxfer.h>
#include <dcmtk/oflog/oflog.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <mutex>
#include <sstream>
#include <vector>

namespace xgauge {
namespace {

namespace fs = std::filesystem;

// DCMTK logs warnings to stderr by default; every problem that matters
// becomes an Error here instead.
void silenceDcmtk() {
  static std::once_flag once;
  std::call_once(once, [] { OFLog::configure(OFLogger::OFF_LOG_LEVEL); });
}

std::string tagName(const DcmTagKey& key) {
  DcmTag tag(key);
  return fmt::format("({:04X},{:04X}) {}", key.getGroup(), key.getElement(), tag.getTagName());
}

uint16_t requiredUint16(DcmDataset& dataset, const DcmTagKey& key, const SourceLocation& where) {
  Uint16 value = 0;
  const OFCondition status = dataset.findAndGetUint16(key, value);
  if (status.bad()) failAt(where, "{}: missing or unreadable ({})", tagName(key), status.text());
  return value;
}

// A decimal-string tag (DS) such as Rescale Slope; `fallback` when absent.
double decimal(DcmDataset& dataset, const DcmTagKey& key, double fallback,
               const SourceLocation& where) {
  if (!dataset.tagExistsWithValue(key)) return fallback;
  Float64 value = 0;
  const OFCondition status = dataset.findAndGetFloat64(key, value);
  if (status.bad() || !std::isfinite(value))
    failAt(where, "{}: not a finite number ({})", tagName(key), status.text());
  return value;
}

// Converts one frame of integer samples with the rescale applied.
template <typename Stored>
Image rescaledFrame(const Stored* samples, int width, int height, unsigned bits_stored,
                    double slope, double intercept, const std::string& label,
                    const SourceLocation& where) {
  const auto mask = static_cast<Stored>(bits_stored >= 8 * sizeof(Stored)
                                            ? ~Stored{0}
                                            : static_cast<Stored>((1u << bits_stored) - 1u));
  Image image(width, height);
  auto pixels = image.pixels();
  for (size_t i = 0; i < pixels.size(); ++i) {
    const double value = slope * static_cast<double>(samples[i] & mask) + intercept;
    if (!(std::abs(value) <= static_cast<double>(std::numeric_limits<float>::max())))
      failAt(where, "pixel ({}, {}){} rescales to {}: beyond the float range", i % size_t(width),
             i / size_t(width), label, value);
    // Slope 1 and intercept 0 give the stored value exactly.
    pixels[i] = static_cast<float>(value);
  }
  return image;
}

}  // namespace

Image readDiconde(const fs::path& path, std::string* sha256, const ExpectedImageSize* expected,
                  int* frames_averaged) {
  const SourceLocation where = SourceLocation::inFile(path.string());
  silenceDcmtk();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) failAt(where, "file does not exist or is not a file");
  const uintmax_t file_size = fs::file_size(path, ec);
  if (ec) failAt(where, "cannot access the file: {}", ec.message());
  // The file's bytes and DCMTK's copy of its elements are held at once.
  if (2 * static_cast<uint64_t>(file_size) > tiffMemoryLimit())
    failAt(where, "the file is {}: reading it needs {}, more than the limit of {} (--max-image-mb)",
           frames::mebibytes(file_size), frames::mebibytes(2 * file_size),
           frames::mebibytes(tiffMemoryLimit()));
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    if (!in) failAt(where, "cannot open the file: {}", std::strerror(errno));
    bytes.resize(static_cast<size_t>(file_size));
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (static_cast<uintmax_t>(in.gcount()) != file_size || in.peek() != EOF)
      failAt(where, "the file changed while it was read; read it again");
  }
  if (sha256) *sha256 = sha256Hex(bytes);
  if (bytes.size() < 132 || bytes.compare(128, 4, "DICM") != 0)
    failAt(where, "not a DICOM file: no 'DICM' after the 128-byte preamble");

  DcmFileFormat format;
  {
    DcmInputBufferStream stream;
    stream.setBuffer(bytes.data(), static_cast<offile_off_t>(bytes.size()));
    stream.setEos();
    format.transferInit();
    const OFCondition status = format.read(stream, EXS_Unknown, EGL_noChange, DCM_MaxReadLength);
    format.transferEnd();
    if (status.bad()) failAt(where, "not a readable DICOM file (DCMTK: {})", status.text());
  }
  bytes = std::string();
  DcmDataset& dataset = *format.getDataset();

  const DcmXfer transfer(dataset.getOriginalXfer());
  if (transfer.isEncapsulated())
    failAt(where,
           "the pixels are compressed ({}, transfer syntax {}): xgauge reads uncompressed DICOM "
           "only; decompress it first (DCMTK: dcmdjpeg, dcmdjpls, dcmdrle)",
           transfer.getXferName(), transfer.getXferID());

  const uint16_t samples_per_pixel = requiredUint16(dataset, DCM_SamplesPerPixel, where);
  if (samples_per_pixel != 1)
    failAt(where, "{} = {}: only single-channel (grey) radiographs are supported",
           tagName(DCM_SamplesPerPixel), samples_per_pixel);
  OFString photometric;
  if (dataset.findAndGetOFString(DCM_PhotometricInterpretation, photometric).bad())
    failAt(where, "{}: missing", tagName(DCM_PhotometricInterpretation));
  if (photometric != "MONOCHROME2")
    failAt(where, "{} = {}: only MONOCHROME2 (0 = black) is supported",
           tagName(DCM_PhotometricInterpretation), photometric.c_str());
  const int rows = requiredUint16(dataset, DCM_Rows, where);
  const int columns = requiredUint16(dataset, DCM_Columns, where);
  if (rows == 0 || columns == 0) failAt(where, "the image has zero size ({}x{})", columns, rows);
  const unsigned bits_allocated = requiredUint16(dataset, DCM_BitsAllocated, where);
  Sint32 frame_count = 1;
  if (dataset.tagExistsWithValue(DCM_NumberOfFrames) &&
      (dataset.findAndGetSint32(DCM_NumberOfFrames, frame_count).bad() || frame_count < 1))
    failAt(where, "{}: expected a whole number from 1", tagName(DCM_NumberOfFrames));
  if (expected && (columns != expected->width || rows != expected->height))
    failAt(where, "is {}x{} pixels but {} is {}x{}", columns, rows, expected->what, expected->width,
           expected->height);

  const bool is_float = dataset.tagExists(DCM_FloatPixelData);
  const size_t pixels_per_frame = size_t(rows) * size_t(columns);
  const auto frames = static_cast<uint64_t>(frame_count);
  frames::checkMemory(where, static_cast<uint64_t>(columns), static_cast<uint64_t>(rows), frames,
                      2 * static_cast<uint64_t>(file_size));
  const auto too_short = [&](const DcmTagKey& key, unsigned long count) {
    if (count < pixels_per_frame * frames)
      failAt(where, "{} holds {} samples but {}x{} pixels x {} frame(s) need {}", tagName(key),
             count, columns, rows, frames, pixels_per_frame * frames);
  };
  frames::FrameMean mean;
  if (is_float) {
    if (bits_allocated != 32)
      failAt(where, "{} with {} = {}; expected 32", tagName(DCM_FloatPixelData),
             tagName(DCM_BitsAllocated), bits_allocated);
    const Float32* samples = nullptr;
    unsigned long count = 0;
    if (dataset.findAndGetFloat32Array(DCM_FloatPixelData, samples, &count).bad() || !samples)
      failAt(where, "{}: unreadable", tagName(DCM_FloatPixelData));
    too_short(DCM_FloatPixelData, count);
    for (uint64_t f = 0; f < frames; ++f) {
      frames::SampleConverter<float> converter;
      if (frames > 1) converter.frame_label = fmt::format(" of frame {}", f + 1);
      Image image(columns, rows);
      const auto* in = reinterpret_cast<const unsigned char*>(samples + f * pixels_per_frame);
      for (int y = 0; y < rows; ++y)
        converter.convert(in + size_t(y) * size_t(columns) * sizeof(float), image.row(y), columns,
                          0, y, columns);
      converter.check(where);
      mean.add(std::move(image));
    }
  } else {
    if (!dataset.tagExists(DCM_PixelData)) failAt(where, "{}: missing", tagName(DCM_PixelData));
    const unsigned bits_stored = requiredUint16(dataset, DCM_BitsStored, where);
    const uint16_t representation = requiredUint16(dataset, DCM_PixelRepresentation, where);
    if (representation != 0)
      failAt(where, "{} = {}: signed samples are not supported (unsigned only)",
             tagName(DCM_PixelRepresentation), representation);
    if (bits_allocated != 8 && bits_allocated != 16)
      failAt(where, "{} = {}: 8 or 16 bits are supported", tagName(DCM_BitsAllocated),
             bits_allocated);
    if (bits_stored == 0 || bits_stored > bits_allocated)
      failAt(where, "{} = {} with {} = {}", tagName(DCM_BitsStored), bits_stored,
             tagName(DCM_BitsAllocated), bits_allocated);
    const double slope = decimal(dataset, DCM_RescaleSlope, 1.0, where);
    const double intercept = decimal(dataset, DCM_RescaleIntercept, 0.0, where);
    const auto label = [&](uint64_t f) {
      return frames > 1 ? fmt::format(" of frame {}", f + 1) : std::string();
    };
    if (bits_allocated == 8) {
      const Uint8* samples = nullptr;
      unsigned long count = 0;
      if (dataset.findAndGetUint8Array(DCM_PixelData, samples, &count).bad() || !samples)
        failAt(where, "{}: unreadable", tagName(DCM_PixelData));
      too_short(DCM_PixelData, count);
      for (uint64_t f = 0; f < frames; ++f)
        mean.add(rescaledFrame(samples + f * pixels_per_frame, columns, rows, bits_stored, slope,
                               intercept, label(f), where));
    } else {
      const Uint16* samples = nullptr;
      unsigned long count = 0;
      if (dataset.findAndGetUint16Array(DCM_PixelData, samples, &count).bad() || !samples)
        failAt(where, "{}: unreadable", tagName(DCM_PixelData));
      too_short(DCM_PixelData, count);
      for (uint64_t f = 0; f < frames; ++f)
        mean.add(rescaledFrame(samples + f * pixels_per_frame, columns, rows, bits_stored, slope,
                               intercept, label(f), where));
    }
  }
  if (frames_averaged) *frames_averaged = mean.count();
  return mean.take();
}

namespace {

// A UID under the root 2.25 (an integer of up to 128 bits, ISO/IEC 9834-8)
// taken from the SHA-256 of `what`: the same image gives the same UIDs.
__extension__ using Uint128 = unsigned __int128;  // GCC and Clang

std::string uidFrom(const std::string& what) {
  const std::string hex = sha256Hex(what);
  Uint128 value = 0;
  for (size_t i = 0; i < 32; ++i)
    value = value * 16 + static_cast<unsigned>(std::stoi(hex.substr(i, 1), nullptr, 16));
  std::string digits;
  do {
    digits.insert(digits.begin(), static_cast<char>('0' + static_cast<int>(value % 10)));
    value /= 10;
  } while (value != 0);
  return "2.25." + digits;
}

void put(const OFCondition& status, const DcmTagKey& key, const SourceLocation& where) {
  if (status.bad()) failAt(where, "cannot set {} ({})", tagName(key), status.text());
}

}  // namespace

void writeDiconde(const fs::path& path, const Image& image, TiffFormat format) {
  const SourceLocation where = SourceLocation::inFile(path.string());
  silenceDcmtk();
  if (image.empty()) throw Error("cannot write an empty image", where);
  if (image.width() > 65535 || image.height() > 65535)
    failAt(where, "cannot write {}x{} pixels: DICOM allows at most 65535 rows and columns",
           image.width(), image.height());
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x)
      if (!std::isfinite(image(x, y)))
        failAt(where, "cannot write pixel ({}, {}) = {}: radiographs hold finite values", x, y,
               image(x, y));
  const bool as_uint16 = format == TiffFormat::kUInt16;
  const auto pixels = image.pixels();
  const std::string identity =
      fmt::format("{}x{} {} ", image.width(), image.height(), as_uint16 ? "u16" : "f32") +
      std::string(reinterpret_cast<const char*>(pixels.data()), pixels.size_bytes());

  DcmFileFormat file;
  DcmDataset& d = *file.getDataset();
  const auto text = [&](const DcmTagKey& key, const std::string& value) {
    put(d.putAndInsertString(key, value.c_str()), key, where);
  };
  const auto number = [&](const DcmTagKey& key, Uint16 value) {
    put(d.putAndInsertUint16(key, value), key, where);
  };
  text(DCM_SOPClassUID, UID_DigitalXRayImageStorageForProcessing);
  text(DCM_SOPInstanceUID, uidFrom("instance " + identity));
  text(DCM_StudyInstanceUID, uidFrom("study " + identity));
  text(DCM_SeriesInstanceUID, uidFrom("series " + identity));
  text(DCM_Modality, "DX");
  text(DCM_Manufacturer, "xgauge");
  number(DCM_SamplesPerPixel, 1);
  text(DCM_PhotometricInterpretation, "MONOCHROME2");
  number(DCM_Rows, static_cast<Uint16>(image.height()));
  number(DCM_Columns, static_cast<Uint16>(image.width()));
  number(DCM_PixelRepresentation, 0);
  if (as_uint16) {
    number(DCM_BitsAllocated, 16);
    number(DCM_BitsStored, 16);
    number(DCM_HighBit, 15);
    std::vector<Uint16> samples(pixels.size());
    for (size_t i = 0; i < pixels.size(); ++i)
      samples[i] = static_cast<Uint16>(
          std::lround(std::clamp(static_cast<double>(pixels[i]), 0.0, 65535.0)));
    put(d.putAndInsertUint16Array(DCM_PixelData, samples.data(), samples.size()), DCM_PixelData,
        where);
  } else {
    number(DCM_BitsAllocated, 32);
    put(d.putAndInsertFloat32Array(DCM_FloatPixelData, pixels.data(), pixels.size()),
        DCM_FloatPixelData, where);
  }

  AtomicFile out(path);
  const OFCondition status =
      file.saveFile(out.tempPath().c_str(), EXS_LittleEndianExplicit, EET_ExplicitLength,
                    EGL_recalcGL, EPD_noChange, 0, 0, EWM_fileformat);
  if (status.bad()) failAt(where, "cannot write the DICOM file ({})", status.text());
  out.commit();
}

}  // namespace xgauge
