#include "xgauge/geometry/stl.h"

#include "xgauge/core/digest.h"
#include "xgauge/core/file.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <string_view>

namespace xgauge {
namespace {

constexpr size_t kBinaryHeaderBytes = 84;    // 80-byte header + uint32 triangle count
constexpr size_t kBinaryTriangleBytes = 50;  // normal, 3 corners (12 floats), uint16

uint32_t readLittleU32(const char* bytes) {
  const auto byte = [&](int i) { return uint32_t{static_cast<uint8_t>(bytes[i])}; };
  return byte(0) | byte(1) << 8 | byte(2) << 16 | byte(3) << 24;
}

TriangleSoup parseBinary(const std::string& bytes, const std::string& file) {
  const uint32_t count = readLittleU32(bytes.data() + 80);
  TriangleSoup soup(count);
  for (uint32_t i = 0; i < count; ++i) {
    // Skip the facet normal (3 floats); read the 3 corners.
    const char* corner = bytes.data() + kBinaryHeaderBytes + i * kBinaryTriangleBytes + 12;
    for (int c = 0; c < 3; ++c) {
      for (int axis = 0; axis < 3; ++axis) {
        const float value = std::bit_cast<float>(readLittleU32(corner + 4 * (3 * c + axis)));
        if (!std::isfinite(value))
          throw Error(fmt::format("triangle {} has a non-finite coordinate", i),
                      SourceLocation::inFile(file));
        soup[i][c][axis] = static_cast<double>(value);
      }
    }
  }
  return soup;
}

// A word as quoted in an error message.
std::string_view shown(std::string_view word) { return word.empty() ? "end of file" : word; }

// Whitespace-separated words of an ASCII STL, with their line numbers.
class AsciiReader {
 public:
  AsciiReader(std::string_view text, std::string file) : text_(text), file_(std::move(file)) {}

  bool atEnd() {
    skipSpace();
    return pos_ == text_.size();
  }
  std::string_view word() {
    skipSpace();
    const size_t start = pos_;
    while (pos_ < text_.size() && !isSpace(text_[pos_])) ++pos_;
    return text_.substr(start, pos_ - start);
  }
  void expect(std::string_view keyword) {
    const std::string_view found = word();
    if (!equalNoCase(found, keyword)) failHere("expected '{}', found '{}'", keyword, shown(found));
  }
  double number() {
    std::string_view found = word();
    if (!found.empty() && found.front() == '+') found.remove_prefix(1);  // from_chars rejects '+'
    double value = 0;
    const auto [end, ec] = std::from_chars(found.data(), found.data() + found.size(), value);
    if (ec != std::errc() || end != found.data() + found.size() || !std::isfinite(value))
      failHere("expected a finite number, found '{}'", shown(found));
    return value;
  }
  // The rest of the line (a solid's name), ignored.
  void skipLine() {
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
  }
  static bool equalNoCase(std::string_view a, std::string_view b) {
    return std::equal(a.begin(), a.end(), b.begin(), b.end(), [](char x, char y) {
      return std::tolower(static_cast<unsigned char>(x)) ==
             std::tolower(static_cast<unsigned char>(y));
    });
  }
  template <typename... Args>
  [[noreturn]] void failHere(fmt::format_string<Args...> format, Args&&... args) {
    SourceLocation where = SourceLocation::inFile(file_);
    where.line = line_;
    throw Error(fmt::format(format, std::forward<Args>(args)...), where);
  }

 private:
  static bool isSpace(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v';
  }
  void skipSpace() {
    while (pos_ < text_.size() && isSpace(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
  }

  std::string_view text_;
  std::string file_;
  size_t pos_ = 0;
  int line_ = 1;
};

// solid NAME (facet normal N N N outer loop (vertex X Y Z){3} endloop endfacet)* endsolid NAME,
// possibly several solids one after the other.
TriangleSoup parseAscii(std::string_view text, const std::string& file) {
  AsciiReader in(text, file);
  TriangleSoup soup;
  while (!in.atEnd()) {
    in.expect("solid");
    in.skipLine();
    for (;;) {
      const std::string_view keyword = in.word();
      if (AsciiReader::equalNoCase(keyword, "endsolid")) break;
      if (!AsciiReader::equalNoCase(keyword, "facet"))
        in.failHere("expected 'facet' or 'endsolid', found '{}'", shown(keyword));
      in.expect("normal");
      for (int i = 0; i < 3; ++i) in.number();
      in.expect("outer");
      in.expect("loop");
      std::array<Vec3, 3>& corners = soup.emplace_back();
      for (Vec3& corner : corners) {
        in.expect("vertex");
        for (int axis = 0; axis < 3; ++axis) corner[axis] = in.number();
      }
      in.expect("endloop");
      in.expect("endfacet");
    }
    in.skipLine();
  }
  return soup;
}

// Binary files carry their size in the header; an ASCII file starts with
// "solid" and holds text only (a binary header may start with "solid" too).
TriangleSoup parseStl(const std::string& bytes, const std::string& file) {
  if (bytes.size() >= kBinaryHeaderBytes) {
    const uint64_t count = readLittleU32(bytes.data() + 80);
    if (kBinaryHeaderBytes + count * kBinaryTriangleBytes == bytes.size())
      return parseBinary(bytes, file);
  }
  const size_t first = bytes.find_first_not_of(" \t\r\n");
  const bool looks_ascii = first != std::string::npos && bytes.compare(first, 5, "solid") == 0 &&
                           std::none_of(bytes.begin(), bytes.end(), [](char c) {
                             const auto byte = static_cast<unsigned char>(c);
                             return byte < 0x09 || (byte > 0x0d && byte < 0x20) || byte == 0x7f;
                           });
  if (looks_ascii) return parseAscii(bytes, file);
  if (bytes.size() < kBinaryHeaderBytes)
    throw Error(fmt::format("not an STL file: {} bytes is too short for a binary STL and it is "
                            "not ASCII STL",
                            bytes.size()),
                SourceLocation::inFile(file));
  const uint64_t count = readLittleU32(bytes.data() + 80);
  throw Error(fmt::format("binary STL is truncated or corrupt: its header declares {} triangles, "
                          "which need {} bytes, but the file has {}",
                          count, kBinaryHeaderBytes + count * kBinaryTriangleBytes, bytes.size()),
              SourceLocation::inFile(file));
}

}  // namespace

TriangleMesh readStl(const std::filesystem::path& path, std::string* sha256) {
  const std::string file = path.string();
  // 256 MiB: 5 million binary triangles, far beyond any part a fit can use.
  const std::string bytes = readFileContents(path, uint64_t{256} << 20, "an STL file");
  if (sha256) *sha256 = sha256Hex(bytes);
  return closedMeshFromSoup(parseStl(bytes, file), file);
}

}  // namespace xgauge
