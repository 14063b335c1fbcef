#include "xgauge/geometry/stl.h"

#include "xgauge/core/file.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <numeric>
#include <sstream>
#include <string_view>
#include <unordered_map>

namespace xgauge {
namespace {

// Three corners per triangle, as stored in the file.
using TriangleSoup = std::vector<std::array<Vec3, 3>>;

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

// Union-find over vertex indices whose root is the smallest index of a set.
class SmallestRootSets {
 public:
  explicit SmallestRootSets(size_t n) : parent_(n) {
    std::iota(parent_.begin(), parent_.end(), uint32_t{0});
  }
  uint32_t root(uint32_t v) {
    while (parent_[v] != v) v = parent_[v] = parent_[parent_[v]];
    return v;
  }
  void join(uint32_t a, uint32_t b) {
    a = root(a), b = root(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<uint32_t> parent_;
};

struct CellHash {
  size_t operator()(const std::array<int64_t, 3>& cell) const {
    uint64_t h = 1469598103934665603ull;
    for (int64_t c : cell) h = (h ^ static_cast<uint64_t>(c)) * 1099511628211ull;
    return static_cast<size_t>(h);
  }
};

// For each vertex, the smallest index of a vertex within `tolerance` of it in
// every coordinate (chains included). Vertices are bucketed in a grid of
// cells `tolerance` wide, so only the 27 surrounding cells need comparing.
std::vector<uint32_t> mergeClose(const std::vector<Vec3>& vertices, const Vec3& origin,
                                 double tolerance) {
  SmallestRootSets sets(vertices.size());
  std::unordered_map<std::array<int64_t, 3>, std::vector<uint32_t>, CellHash> cells;
  auto cellOf = [&](const Vec3& v) {
    const Vec3 scaled = ((v - origin) / tolerance).array().floor().matrix();
    return std::array<int64_t, 3>{static_cast<int64_t>(scaled.x()),
                                  static_cast<int64_t>(scaled.y()),
                                  static_cast<int64_t>(scaled.z())};
  };
  for (uint32_t i = 0; i < vertices.size(); ++i) cells[cellOf(vertices[i])].push_back(i);
  for (uint32_t i = 0; i < vertices.size(); ++i) {
    const auto cell = cellOf(vertices[i]);
    for (int64_t dx = -1; dx <= 1; ++dx)
      for (int64_t dy = -1; dy <= 1; ++dy)
        for (int64_t dz = -1; dz <= 1; ++dz) {
          const auto found = cells.find({cell[0] + dx, cell[1] + dy, cell[2] + dz});
          if (found == cells.end()) continue;
          for (uint32_t j : found->second)
            if (j > i && (vertices[i] - vertices[j]).cwiseAbs().maxCoeff() <= tolerance)
              sets.join(i, j);
        }
  }
  std::vector<uint32_t> representative(vertices.size());
  for (uint32_t i = 0; i < vertices.size(); ++i) representative[i] = sets.root(i);
  return representative;
}

struct PointHash {
  size_t operator()(const Vec3& p) const {  // +0.0 and -0.0 hash alike
    size_t h = std::hash<double>{}(p.x());
    h = h * 1000003u ^ std::hash<double>{}(p.y());
    return h * 1000003u ^ std::hash<double>{}(p.z());
  }
};

TriangleMesh weld(const TriangleSoup& soup, const std::string& file) {
  // Exact matches first.
  TriangleMesh mesh;
  std::unordered_map<Vec3, uint32_t, PointHash> index_of;
  mesh.triangles.reserve(soup.size());
  for (const auto& corners : soup) {
    Triangle& t = mesh.triangles.emplace_back();
    for (int c = 0; c < 3; ++c) {
      const auto [it, added] =
          index_of.try_emplace(corners[c], static_cast<uint32_t>(mesh.vertices.size()));
      if (added) mesh.vertices.push_back(corners[c]);
      t[c] = it->second;
    }
  }

  // Then near matches; keep the surviving vertices in their first-seen order.
  const BoundingBox box = boundingBox(mesh);
  const double tolerance = kStlWeldTolerance * box.diagonal();
  if (tolerance > 0) {
    const std::vector<uint32_t> representative = mergeClose(mesh.vertices, box.min_mm, tolerance);
    std::vector<uint32_t> new_index(mesh.vertices.size());
    std::vector<Vec3> kept;
    for (uint32_t i = 0; i < mesh.vertices.size(); ++i) {
      if (representative[i] == i) {
        new_index[i] = static_cast<uint32_t>(kept.size());
        kept.push_back(mesh.vertices[i]);
      } else {
        new_index[i] = new_index[representative[i]];  // representative[i] < i
      }
    }
    mesh.vertices = std::move(kept);
    for (Triangle& t : mesh.triangles)
      for (uint32_t& v : t) v = new_index[v];
  }

  // Triangles that lost a corner to welding cover no area: drop them.
  const size_t before = mesh.triangles.size();
  std::erase_if(mesh.triangles,
                [](const Triangle& t) { return t[0] == t[1] || t[1] == t[2] || t[2] == t[0]; });
  if (mesh.triangles.size() != before)
    spdlog::warn("{}: dropped {} triangles that collapsed when welding vertices", file,
                 before - mesh.triangles.size());
  return mesh;
}

}  // namespace

TriangleMesh readStl(const std::filesystem::path& path) {
  const std::string file = path.string();
  // 256 MiB: 5 million binary triangles, far beyond any part a fit can use.
  const std::string bytes = readFileContents(path, uint64_t{256} << 20, "an STL file");
  TriangleMesh mesh = weld(parseStl(bytes, file), file);
  const MeshCheck check = checkClosedMesh(mesh);
  if (check.problem == MeshCheck::Problem::kInward) {
    spdlog::warn("{}: triangles face inward; flipped them all", file);
    flipOrientation(mesh);
  } else if (!check.ok()) {
    throw Error(check.message, SourceLocation::inFile(file));
  }
  noteZeroAreaTriangles(check, file);
  return mesh;
}

}  // namespace xgauge
