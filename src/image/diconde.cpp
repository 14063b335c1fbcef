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
#include <cctype>
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

uint16_t u16(const std::string& b, size_t at, bool big) {
  const auto c0 = static_cast<unsigned char>(b[at]), c1 = static_cast<unsigned char>(b[at + 1]);
  return static_cast<uint16_t>(big ? (c0 << 8) | c1 : (c1 << 8) | c0);
}

uint32_t u32(const std::string& b, size_t at, bool big) {
  const uint32_t lo = u16(b, at, big), hi = u16(b, at + 2, big);
  return big ? (lo << 16) | hi : (hi << 16) | lo;
}

constexpr uint32_t kUndefinedLength = 0xffffffffu;

// Walks every element header of the file (group 0002 in explicit VR
// little-endian, then the data set in its transfer syntax), descending into
// sequences and items, and refuses any value longer than the bytes left:
// DCMTK allocates a value's declared length before reading it, so a
// 300-byte file declaring a 3 GB element would otherwise allocate 3 GB.
// Returns the transfer syntax UID; refuses syntaxes other than the three
// native ones, naming them.
std::string checkElementLengths(const std::string& bytes, const SourceLocation& where) {
  const size_t size = bytes.size();
  size_t at = 132;
  std::string syntax;
  bool implicit = false, big = false, in_meta = true;
  size_t meta_end = 0;  // from (0002,0000), when given
  while (at < size) {
    if (size - at < 8) failAt(where, "the file ends within an element's header at byte {}", at);
    if (in_meta && u16(bytes, at, false) != 0x0002) {
      // The data set starts: its transfer syntax decides the encoding.
      // DCMTK reads the meta group as long as its group length says: the
      // two must agree, or DCMTK would parse other bytes than these.
      if (meta_end != 0 && at != meta_end)
        failAt(where,
               "the File Meta Information Group Length (0002,0000) ends it at byte {} but group "
               "0002 ends at byte {}: corrupt",
               meta_end, at);
      in_meta = false;
      if (syntax == UID_LittleEndianImplicitTransferSyntax) {
        implicit = true;
      } else if (syntax == UID_BigEndianExplicitTransferSyntax) {
        big = true;
      } else if (syntax.empty()) {
        failAt(where, "the file meta information states no Transfer Syntax UID (0002,0010)");
      } else if (syntax != UID_LittleEndianExplicitTransferSyntax) {
        const DcmXfer transfer(syntax.c_str());
        failAt(where,
               "the transfer syntax is {} ({}): xgauge reads uncompressed DICOM only (implicit "
               "or explicit VR little-endian, explicit big-endian); decompress it first (DCMTK: "
               "dcmdjpeg, dcmdjpls, dcmdrle, dcmconv +te)",
               transfer.getXfer() == EXS_Unknown ? "unknown" : transfer.getXferName(), syntax);
      }
    }
    const bool big_here = !in_meta && big, implicit_here = !in_meta && implicit;
    const uint16_t group = u16(bytes, at, big_here), element = u16(bytes, at + 2, big_here);
    uint32_t length = 0;
    bool descend = false;
    if (group == 0xfffe) {
      // Items and delimiters: an item's content is elements.
      length = u32(bytes, at + 4, big_here);
      at += 8;
      if (element == 0xe000) continue;
      if (length != 0) failAt(where, "a delimiter of nonzero length at byte {}", at - 8);
      continue;
    }
    std::string vr;
    if (implicit_here) {
      length = u32(bytes, at + 4, big_here);
      descend = DcmTag(DcmTagKey(group, element)).getEVR() == EVR_SQ;
      at += 8;
    } else {
      vr = bytes.substr(at + 4, 2);
      // Not a VR at all: DCMTK would guess at the encoding from here on.
      if (!std::isupper(static_cast<unsigned char>(vr[0])) ||
          !std::isupper(static_cast<unsigned char>(vr[1])))
        failAt(where, "element ({:04X},{:04X}) at byte {} has no valid VR: corrupt", group, element,
               at);
      // The VRs with a 2-byte length; every other VR, unknown ones included
      // (as DCMTK reads them), has 2 reserved bytes and a 4-byte length.
      static constexpr std::string_view kShortVrs[] = {"AE", "AS", "AT", "CS", "DA", "DS", "DT",
                                                       "FL", "FD", "IS", "LO", "LT", "PN", "SH",
                                                       "SL", "SS", "ST", "TM", "UI", "UL", "US"};
      if (std::find(std::begin(kShortVrs), std::end(kShortVrs), vr) == std::end(kShortVrs)) {
        if (size - at < 12)
          failAt(where, "the file ends within an element's header at byte {}", at);
        length = u32(bytes, at + 8, big_here);
        at += 12;
      } else {
        length = u16(bytes, at + 6, big_here);
        at += 8;
      }
      descend = vr == "SQ";
    }
    if (length == kUndefinedLength) {
      if (group == 0x7fe0)
        failAt(where, "({:04X},{:04X}) has undefined length: encapsulated (compressed) pixels",
               group, element);
      if (!descend)
        failAt(where, "({:04X},{:04X}) {} has undefined length: not supported", group, element,
               vr.empty() ? "(implicit VR)" : vr);
      continue;
    }
    if (length > size - at)
      failAt(where,
             "element ({:04X},{:04X}) at byte {} declares {} bytes but the file has {} left: it "
             "is truncated or corrupt",
             group, element, at, length, size - at);
    if (in_meta && group == 0x0002 && element == 0x0000 && length == 4)
      meta_end = at + 4 + u32(bytes, at, false);
    if (in_meta && group == 0x0002 && element == 0x0010) {
      syntax = bytes.substr(at, length);
      while (!syntax.empty() && (syntax.back() == '\0' || syntax.back() == ' ')) syntax.pop_back();
    }
    if (!descend) at += length;
  }
  return syntax;
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
  checkElementLengths(bytes, where);

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
