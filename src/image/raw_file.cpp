#include "xgauge/image/raw_file.h"

#include "frames.h"
#include "xgauge/core/atomic_file.h"
#include "xgauge/core/config.h"
#include "xgauge/core/did_you_mean.h"
#include "xgauge/core/digest.h"
#include "xgauge/core/error.h"

#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <string_view>
#include <vector>

namespace xgauge {
namespace {

namespace fs = std::filesystem;

constexpr std::array<std::string_view, 6> kKeys = {"width",      "height", "type",
                                                   "byte_order", "offset", "frames"};
__extension__ using Uint128 = unsigned __int128;  // GCC and Clang

constexpr std::string_view kTypes = "uint8, uint16, uint32, float32 or float64";
// More frames than any lab averages; keeps the frame count an int.
constexpr int64_t kMaxFrames = 1 << 20;

struct RawLayout {
  int64_t width = 0, height = 0;
  RawSampleType type = RawSampleType::kUInt16;
  bool big_endian = false;
  int64_t offset = 0;
  int64_t frames = 1;
};

size_t bytesOf(RawSampleType type) {
  switch (type) {
    case RawSampleType::kUInt8:
      return 1;
    case RawSampleType::kUInt16:
      return 2;
    case RawSampleType::kUInt32:
    case RawSampleType::kFloat32:
      return 4;
    case RawSampleType::kFloat64:
      return 8;
  }
  return 0;
}

std::optional<RawSampleType> typeNamed(std::string_view name) {
  if (name == "uint8") return RawSampleType::kUInt8;
  if (name == "uint16") return RawSampleType::kUInt16;
  if (name == "uint32") return RawSampleType::kUInt32;
  if (name == "float32") return RawSampleType::kFloat32;
  if (name == "float64") return RawSampleType::kFloat64;
  return std::nullopt;
}

// The whole file's bytes; `what` names it in errors.
std::string readWhole(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    failAt(SourceLocation::inFile(path.string()), "cannot open the file: {}", std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) failAt(SourceLocation::inFile(path.string()), "cannot read the file");
  return std::move(text).str();
}

// The JSON sidecar: an object with the keys above, nothing else.
RawLayout parseJsonSidecar(const std::string& text, const fs::path& sidecar) {
  const ConfigNode root = ConfigNode::parse(text, sidecar.string());
  if (!root.isObject())
    root.fail("expected an object with the keys width, height, type, byte_order, offset, frames");
  RawLayout layout;
  constexpr int64_t kMaxSide = std::numeric_limits<int>::max();
  layout.width = root.at("width").integer(1, kMaxSide);
  layout.height = root.at("height").integer(1, kMaxSide);
  const ConfigNode type = root.at("type");
  const auto sample = typeNamed(type.string());
  if (!sample) type.fail(fmt::format("expected {}, got '{}'", kTypes, type.string()));
  layout.type = *sample;
  if (const auto order = root.find("byte_order")) {
    const std::string value = order->string();
    if (value != "little" && value != "big")
      order->fail(fmt::format("expected little or big, got '{}'", value));
    layout.big_endian = value == "big";
  } else if (layout.type != RawSampleType::kUInt8) {
    root.fail("missing key 'byte_order' (little or big): samples of more than one byte need it");
  }
  if (const auto offset = root.find("offset"))
    layout.offset = offset->integer(0, std::numeric_limits<int64_t>::max() / 2);
  if (const auto frames = root.find("frames")) layout.frames = frames->integer(1, kMaxFrames);
  root.finish();
  return layout;
}

// The INI sidecar: `key = value` lines under [raw]; `#` or `;` starts a
// comment line. Errors give the line.
RawLayout parseIniSidecar(const std::string& text, const fs::path& sidecar) {
  struct Value {
    std::string text;
    int line = 0;
  };
  std::map<std::string, Value, std::less<>> values;
  bool in_raw = false, saw_raw = false;
  const auto where = [&](int line) {
    SourceLocation at = SourceLocation::inFile(sidecar.string());
    at.line = line;
    return at;
  };
  const auto trim = [](std::string_view s) {
    const auto first = s.find_first_not_of(" \t\r");
    if (first == std::string_view::npos) return std::string_view();
    return s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
  };
  std::istringstream lines(text);
  std::string raw_line;
  for (int number = 1; std::getline(lines, raw_line); ++number) {
    const std::string_view line = trim(raw_line);
    if (line.empty() || line.front() == '#' || line.front() == ';') continue;
    if (line.front() == '[') {
      if (line.back() != ']') failAt(where(number), "expected a section header such as [raw]");
      const std::string_view section = trim(line.substr(1, line.size() - 2));
      if (section != "raw")
        failAt(where(number), "unknown section [{}]; the keys go under [raw]", section);
      if (saw_raw) failAt(where(number), "section [raw] appears twice");
      in_raw = saw_raw = true;
      continue;
    }
    const auto equals = line.find('=');
    if (equals == std::string_view::npos)
      failAt(where(number), "expected 'key = value', got '{}'", line.substr(0, 60));
    const std::string key(trim(line.substr(0, equals)));
    std::string value(trim(line.substr(equals + 1)));
    if (value.size() >= 2 && value.front() == '"' && value.back() == '"')
      value = value.substr(1, value.size() - 2);
    if (!in_raw) failAt(where(number), "key '{}' before the section [raw]", key.substr(0, 60));
    if (std::find(kKeys.begin(), kKeys.end(), key) == kKeys.end())
      failAt(where(number), "unknown key '{}'{}", key.substr(0, 60),
             didYouMean(key, {kKeys.begin(), kKeys.end()}));
    if (values.count(key)) failAt(where(number), "key '{}' appears twice", key);
    values[key] = {value, number};
  }
  if (!saw_raw) failAt(where(0), "no section [raw]");

  const auto integer = [&](std::string_view key, int64_t min, int64_t max,
                           std::optional<int64_t> fallback) -> int64_t {
    const auto it = values.find(key);
    if (it == values.end()) {
      if (fallback) return *fallback;
      failAt(where(0), "missing key '{}' in [raw]", key);
    }
    const std::string& text_value = it->second.text;
    int64_t value = 0;
    const auto [end, error] =
        std::from_chars(text_value.data(), text_value.data() + text_value.size(), value);
    if (error != std::errc() || end != text_value.data() + text_value.size())
      failAt(where(it->second.line), "{}: expected a whole number, got '{}'", key,
             text_value.substr(0, 60));
    if (value < min || value > max)
      failAt(where(it->second.line), "{}: {} lies outside [{}, {}]", key, value, min, max);
    return value;
  };
  RawLayout layout;
  constexpr int64_t kMaxSide = std::numeric_limits<int>::max();
  layout.width = integer("width", 1, kMaxSide, std::nullopt);
  layout.height = integer("height", 1, kMaxSide, std::nullopt);
  const auto type = values.find("type");
  if (type == values.end()) failAt(where(0), "missing key 'type' in [raw]");
  const auto sample = typeNamed(type->second.text);
  if (!sample)
    failAt(where(type->second.line), "type: expected {}, got '{}'", kTypes,
           type->second.text.substr(0, 60));
  layout.type = *sample;
  if (const auto order = values.find("byte_order"); order != values.end()) {
    if (order->second.text != "little" && order->second.text != "big")
      failAt(where(order->second.line), "byte_order: expected little or big, got '{}'",
             order->second.text.substr(0, 60));
    layout.big_endian = order->second.text == "big";
  } else if (layout.type != RawSampleType::kUInt8) {
    failAt(where(0),
           "missing key 'byte_order' (little or big) in [raw]: samples of more than one byte "
           "need it");
  }
  layout.offset = integer("offset", 0, std::numeric_limits<int64_t>::max() / 2, 0);
  layout.frames = integer("frames", 1, kMaxFrames, 1);
  return layout;
}

struct FileCloser {
  void operator()(std::FILE* file) const { std::fclose(file); }
};

// Reads exactly `bytes` into `out`, feeding the digest; false at end of file.
bool readExactly(std::FILE* file, unsigned char* out, size_t bytes, Sha256* hash) {
  if (bytes == 0) return true;
  if (std::fread(out, 1, bytes, file) != bytes) return false;
  if (hash) hash->update(out, bytes);
  return true;
}

template <typename Sample>
Image readFrames(std::FILE* file, const RawLayout& layout, Sha256* hash,
                 const SourceLocation& where) {
  const int w = static_cast<int>(layout.width), h = static_cast<int>(layout.height);
  frames::FrameMean mean;
  std::vector<unsigned char> row(static_cast<size_t>(w) * sizeof(Sample));
  for (int64_t frame = 0; frame < layout.frames; ++frame) {
    frames::SampleConverter<Sample> converter;
    converter.swap_bytes = layout.big_endian != (std::endian::native == std::endian::big);
    if (layout.frames > 1) converter.frame_label = fmt::format(" of frame {}", frame + 1);
    Image image(w, h);
    for (int y = 0; y < h; ++y) {
      if (!readExactly(file, row.data(), row.size(), hash))
        failAt(where, "the file ends in row {} of frame {} (it was shortened while read?)", y,
               frame + 1);
      converter.convert(row.data(), image.row(y), w, 0, y, w);
    }
    converter.check(where);
    mean.add(std::move(image));
  }
  return mean.take();
}

}  // namespace

std::optional<fs::path> rawSidecarOf(const fs::path& raw) {
  std::error_code ec;
  for (const char* extension : {".json", ".ini"}) {
    fs::path sidecar = raw;
    sidecar += extension;
    if (fs::is_regular_file(sidecar, ec)) return sidecar;
  }
  return std::nullopt;
}

Image readRawRadiograph(const fs::path& raw, std::string* sha256, const ExpectedImageSize* expected,
                        int* frames_averaged) {
  const SourceLocation where = SourceLocation::inFile(raw.string());
  fs::path json = raw, ini = raw;
  json += ".json";
  ini += ".ini";
  std::error_code ec;
  const bool has_json = fs::is_regular_file(json, ec), has_ini = fs::is_regular_file(ini, ec);
  if (!has_json && !has_ini)
    failAt(where,
           "not a TIFF, HDF5 or DICOM file, and no sidecar {} or {} describes it as raw samples",
           json.filename().string(), ini.filename().string());
  if (has_json && has_ini)
    failAt(where, "two sidecars, {} and {}: keep one", json.filename().string(),
           ini.filename().string());
  const fs::path sidecar = has_json ? json : ini;
  // The sidecar's bytes are parsed and hashed from one read. A few lines of
  // text: anything longer is not a sidecar.
  constexpr uintmax_t kMaxSidecarBytes = 1 << 16;
  if (fs::file_size(sidecar, ec) > kMaxSidecarBytes)
    failAt(SourceLocation::inFile(sidecar.string()),
           "a sidecar of more than {} bytes: not a sidecar", kMaxSidecarBytes);
  const std::string sidecar_text = readWhole(sidecar);
  const RawLayout layout =
      has_json ? parseJsonSidecar(sidecar_text, sidecar) : parseIniSidecar(sidecar_text, sidecar);

  if (expected && (layout.width != expected->width || layout.height != expected->height))
    failAt(where, "is {}x{} pixels (its sidecar {}) but {} is {}x{}", layout.width, layout.height,
           sidecar.filename().string(), expected->what, expected->width, expected->height);

  const std::unique_ptr<std::FILE, FileCloser> file(std::fopen(raw.c_str(), "rb"));
  if (!file) failAt(where, "cannot open the file: {}", std::strerror(errno));
  struct stat info {};
  if (::fstat(fileno(file.get()), &info) != 0 || !S_ISREG(info.st_mode))
    failAt(where, "not a regular file");
  const auto file_bytes = static_cast<uint64_t>(info.st_size);

  // The declared length, without overflow (every factor is below 2^31, the
  // frames below 2^20, the offset below 2^62).
  const size_t sample_bytes = bytesOf(layout.type);
  const Uint128 declared = static_cast<Uint128>(layout.width) *
                               static_cast<uint64_t>(layout.height) *
                               static_cast<uint64_t>(layout.frames) * sample_bytes +
                           static_cast<uint64_t>(layout.offset);
  if (declared != file_bytes) {
    const std::string declared_text = declared > std::numeric_limits<uint64_t>::max()
                                          ? std::string("more than 2^64")
                                          : fmt::format("{}", static_cast<uint64_t>(declared));
    failAt(where,
           "is {} bytes long but its sidecar {} declares {} bytes ({} frame(s) of {}x{} samples of "
           "{} bytes after an offset of {})",
           file_bytes, sidecar.filename().string(), declared_text, layout.frames, layout.width,
           layout.height, sample_bytes, layout.offset);
  }
  frames::checkMemory(where, static_cast<uint64_t>(layout.width),
                      static_cast<uint64_t>(layout.height), static_cast<uint64_t>(layout.frames),
                      static_cast<uint64_t>(layout.width) * sample_bytes);

  std::optional<Sha256> hash;
  if (sha256) hash.emplace();
  Sha256* digest = hash ? &*hash : nullptr;
  // The header: skipped, hashed.
  {
    std::vector<unsigned char> skipped(size_t{1} << 16);
    for (int64_t left = layout.offset; left > 0;) {
      const size_t chunk = static_cast<size_t>(std::min<int64_t>(left, int64_t{1} << 16));
      if (!readExactly(file.get(), skipped.data(), chunk, digest))
        failAt(where, "the file ends within its {}-byte header", layout.offset);
      left -= static_cast<int64_t>(chunk);
    }
  }
  Image image;
  switch (layout.type) {
    case RawSampleType::kUInt8:
      image = readFrames<uint8_t>(file.get(), layout, digest, where);
      break;
    case RawSampleType::kUInt16:
      image = readFrames<uint16_t>(file.get(), layout, digest, where);
      break;
    case RawSampleType::kUInt32:
      image = readFrames<uint32_t>(file.get(), layout, digest, where);
      break;
    case RawSampleType::kFloat32:
      image = readFrames<float>(file.get(), layout, digest, where);
      break;
    case RawSampleType::kFloat64:
      image = readFrames<double>(file.get(), layout, digest, where);
      break;
  }
  if (std::fgetc(file.get()) != EOF) failAt(where, "the file grew while it was read");
  if (hash) {
    hash->update(sidecar_text.data(), sidecar_text.size());
    *sha256 = hash->hex();
  }
  if (frames_averaged) *frames_averaged = static_cast<int>(layout.frames);
  return image;
}

void writeRawRadiograph(const fs::path& raw, const Image& image, TiffFormat format) {
  const SourceLocation where = SourceLocation::inFile(raw.string());
  if (image.empty()) throw Error("cannot write an empty image", where);
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x)
      if (!std::isfinite(image(x, y)))
        failAt(where, "cannot write pixel ({}, {}) = {}: radiographs hold finite values", x, y,
               image(x, y));
  fs::path json = raw, ini = raw;
  json += ".json";
  ini += ".ini";
  std::error_code ec;
  if (fs::exists(ini, ec))
    failAt(where, "a sidecar {} exists already and would contradict the {} written: remove it",
           ini.filename().string(), json.filename().string());

  const bool as_uint16 = format == TiffFormat::kUInt16;
  AtomicFile raw_file(raw), sidecar_file(json);
  {
    std::ofstream out(raw_file.tempPath(), std::ios::binary);
    if (!out) failAt(where, "cannot create the file: {}", std::strerror(errno));
    std::vector<unsigned char> row(static_cast<size_t>(image.width()) * (as_uint16 ? 2 : 4));
    for (int y = 0; y < image.height(); ++y) {
      const float* in = image.row(y);
      for (int x = 0; x < image.width(); ++x) {
        // Little-endian whatever the machine.
        uint32_t bits = 0;
        if (as_uint16) {
          bits = static_cast<uint16_t>(
              std::lround(std::clamp(static_cast<double>(in[x]), 0.0, 65535.0)));
          row[2 * size_t(x)] = static_cast<unsigned char>(bits & 0xff);
          row[2 * size_t(x) + 1] = static_cast<unsigned char>(bits >> 8);
        } else {
          bits = std::bit_cast<uint32_t>(in[x]);
          for (int b = 0; b < 4; ++b)
            row[4 * size_t(x) + size_t(b)] = static_cast<unsigned char>((bits >> (8 * b)) & 0xff);
        }
      }
      out.write(reinterpret_cast<const char*>(row.data()),
                static_cast<std::streamsize>(row.size()));
    }
    out.close();
    if (!out) failAt(where, "cannot write the file (disk full?)");
  }
  {
    std::ofstream out(sidecar_file.tempPath(), std::ios::binary);
    out << fmt::format(
        "{{\n  \"width\": {},\n  \"height\": {},\n  \"type\": \"{}\",\n  \"byte_order\": "
        "\"little\",\n  \"offset\": 0,\n  \"frames\": 1\n}}\n",
        image.width(), image.height(), as_uint16 ? "uint16" : "float32");
    out.close();
    if (!out) failAt(SourceLocation::inFile(json.string()), "cannot write the file (disk full?)");
  }
  raw_file.commit();
  sidecar_file.commit();
}

}  // namespace xgauge
