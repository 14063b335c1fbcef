#include "xgauge/geometry/stl.h"
#include "xgauge/geometry/part_model.h"

#include "test_files.h"

#include <gtest/gtest.h>

#include <bit>
#include <cstring>

namespace xgauge {
namespace {

using testing::writeTestFile;

// The reference cuboid (20 x 30 x 10 mm, centred) as a triangle soup.
std::vector<std::array<Vec3, 3>> cuboidSoup() {
  std::vector<Vec3> v;
  for (int i = 0; i < 8; ++i) v.emplace_back(i & 1 ? 10 : -10, i & 2 ? 15 : -15, i & 4 ? 5 : -5);
  const std::vector<Triangle> triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6},
                                           {0, 1, 5}, {0, 5, 4}, {2, 6, 7}, {2, 7, 3},
                                           {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  std::vector<std::array<Vec3, 3>> soup;
  for (const Triangle& t : triangles) soup.push_back({v[t[0]], v[t[1]], v[t[2]]});
  return soup;
}

std::string binaryStl(const std::vector<std::array<Vec3, 3>>& soup) {
  static_assert(std::endian::native == std::endian::little);
  std::string bytes(80, ' ');
  bytes.replace(0, 11, "xgauge test");
  auto put = [&](const void* data, size_t size) {
    bytes.append(static_cast<const char*>(data), size);
  };
  const auto count = static_cast<uint32_t>(soup.size());
  put(&count, 4);
  for (const auto& corners : soup) {
    const float normal[3] = {0, 0, 0};
    put(normal, sizeof normal);
    for (const Vec3& c : corners)
      for (int axis = 0; axis < 3; ++axis) {
        const auto value = static_cast<float>(c[axis]);
        put(&value, 4);
      }
    const uint16_t attribute = 0;
    put(&attribute, 2);
  }
  return bytes;
}

std::string asciiStl(const std::vector<std::array<Vec3, 3>>& soup) {
  std::string text = "solid cuboid made by a test\n";
  for (const auto& corners : soup) {
    text += "  facet normal 0 0 0\n    outer loop\n";
    for (const Vec3& c : corners)
      text += fmt::format("      vertex {:e} {:e} {:e}\n", c.x(), c.y(), c.z());
    text += "    endloop\n  endfacet\n";
  }
  return text + "endsolid cuboid made by a test\n";
}

void expectCuboid(const TriangleMesh& mesh) {
  EXPECT_EQ(mesh.vertices.size(), 8u);
  EXPECT_EQ(mesh.triangles.size(), 12u);
  EXPECT_TRUE(checkClosedMesh(mesh).ok());
  EXPECT_NEAR(signedVolume(mesh), 20.0 * 30.0 * 10.0, 1e-9);
}

TEST(Stl, BinaryCuboidIsWelded) {
  expectCuboid(readStl(writeTestFile("cuboid.stl", binaryStl(cuboidSoup()))));
}

TEST(Stl, AsciiCuboidIsWelded) {
  expectCuboid(readStl(writeTestFile("cuboid.stl", asciiStl(cuboidSoup()))));
}

TEST(Stl, NearlyEqualAsciiCoordinatesAreWeldedWithinTolerance) {
  // One corner written 1e-13 mm off (far below 1e-9 of the 37 mm diagonal).
  auto soup = cuboidSoup();
  soup[5][1].x() += 1e-13;
  // Shortest round-trip formatting keeps the offset ({:e} would round it away).
  std::string text = "solid near\n";
  for (const auto& corners : soup) {
    text += "facet normal 0 0 0\nouter loop\n";
    for (const Vec3& c : corners) text += fmt::format("vertex {} {} {}\n", c.x(), c.y(), c.z());
    text += "endloop\nendfacet\n";
  }
  text += "endsolid near\n";
  expectCuboid(readStl(writeTestFile("near.stl", text)));
}

TEST(Stl, InwardMeshIsFlipped) {
  auto soup = cuboidSoup();
  for (auto& corners : soup) std::swap(corners[1], corners[2]);
  const TriangleMesh mesh = readStl(writeTestFile("inward.stl", binaryStl(soup)));
  EXPECT_NEAR(signedVolume(mesh), 6000.0, 1e-9);
}

TEST(Stl, DeviceIsRefused) {
  try {
    readStl("/dev/zero");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/zero: is not a regular file"), std::string::npos)
        << e.what();
  }
}

TEST(Stl, TruncatedBinaryIsRejected) {
  std::string bytes = binaryStl(cuboidSoup());
  bytes.resize(bytes.size() - 20);
  const auto path = writeTestFile("truncated.stl", bytes);
  try {
    readStl(path);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.where().file, path.string());
    EXPECT_EQ(e.message(),
              "binary STL is truncated or corrupt: its header declares 12 triangles, which need "
              "684 bytes, but the file has 664");
  }
  EXPECT_THROW(readStl(writeTestFile("short.stl", std::string(30, '\x01'))), Error);
}

TEST(Stl, AsciiSyntaxErrorNamesTheLine) {
  std::string text = asciiStl(cuboidSoup());
  // Line 5 is the second vertex of the first facet; drop its z.
  const size_t line5 = [&] {
    size_t pos = 0;
    for (int i = 0; i < 4; ++i) pos = text.find('\n', pos) + 1;
    return pos;
  }();
  const size_t end = text.find('\n', line5);
  text.replace(line5, end - line5, "      vertex 1 2");
  try {
    readStl(writeTestFile("bad.stl", text));
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.where().line, 6);
    EXPECT_EQ(e.message(), "expected a finite number, found 'vertex'");
  }
}

TEST(Stl, OpenMeshIsRejected) {
  auto soup = cuboidSoup();
  soup.pop_back();
  try {
    readStl(writeTestFile("open.stl", binaryStl(soup)));
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(e.message().find("the mesh is open"), std::string::npos) << e.what();
  }
}

TEST(Stl, PartModelFromStlHasNoDimensions) {
  const auto path = writeTestFile("fixed_cuboid.stl", binaryStl(cuboidSoup()));
  const PartModel model = PartModel::fromStl(path);
  EXPECT_EQ(model.name(), "fixed_cuboid");
  EXPECT_TRUE(model.dimensions().empty());
  EXPECT_EQ(model.triangles().size(), 12u);
  const TriangleMesh mesh = model.mesh({});
  EXPECT_NEAR(signedVolume(mesh), 6000.0, 1e-9);
  EXPECT_THROW(model.dimensionIndex("width"), Error);
}

}  // namespace
}  // namespace xgauge
