#include "xgauge/image/preview.h"

#include "test_folder.h"

#include <gtest/gtest.h>

#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#define STBI_ONLY_PNG
#include <stb_image.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <string>

namespace xgauge {
namespace {

struct PngHeader {
  uint32_t width = 0;
  uint32_t height = 0;
  int bit_depth = 0;
  int colour_type = 0;  // 0 grey, 2 RGB
};

// Parses the signature and the IHDR chunk, which the PNG standard puts first.
PngHeader readPngHeader(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char bytes[26] = {};
  in.read(reinterpret_cast<char*>(bytes), sizeof(bytes));
  EXPECT_TRUE(in) << "short file " << path;
  const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  EXPECT_EQ(std::memcmp(bytes, signature, 8), 0);
  EXPECT_EQ(std::string(reinterpret_cast<char*>(bytes + 12), 4), "IHDR");
  const auto big_endian = [&](int at) {
    return uint32_t{bytes[at]} << 24 | uint32_t{bytes[at + 1]} << 16 |
           uint32_t{bytes[at + 2]} << 8 | uint32_t{bytes[at + 3]};
  };
  EXPECT_EQ(big_endian(8), 13u);  // IHDR length
  return {big_endian(16), big_endian(20), bytes[24], bytes[25]};
}

// Decoded pixels, `channels` bytes each.
struct Decoded {
  std::unique_ptr<unsigned char, decltype(&stbi_image_free)> pixels{nullptr, &stbi_image_free};
  int width = 0;
  int height = 0;
  int channels = 0;
  const unsigned char* at(int x, int y) const {
    return pixels.get() + (static_cast<size_t>(y) * width + x) * static_cast<size_t>(channels);
  }
};

Decoded decodePng(const std::filesystem::path& path) {
  Decoded decoded;
  decoded.pixels.reset(
      stbi_load(path.c_str(), &decoded.width, &decoded.height, &decoded.channels, 0));
  EXPECT_NE(decoded.pixels, nullptr) << stbi_failure_reason();
  return decoded;
}

TEST(GreyLevel, LinearWindowClamped) {
  EXPECT_EQ(greyLevel(10.0, 10.0, 20.0), 0);
  EXPECT_EQ(greyLevel(20.0, 10.0, 20.0), 255);
  EXPECT_EQ(greyLevel(15.0, 10.0, 20.0), 128);  // 127.5 rounds up
  EXPECT_EQ(greyLevel(12.0, 10.0, 20.0), 51);
  EXPECT_EQ(greyLevel(-1e9, 10.0, 20.0), 0);
  EXPECT_EQ(greyLevel(1e9, 10.0, 20.0), 255);
  EXPECT_EQ(greyLevel(std::numeric_limits<double>::quiet_NaN(), 10.0, 20.0), 0);
}

TEST(AutoWindow, PercentilesAndDegenerateImages) {
  Image image(201, 1);
  for (int x = 0; x < 201; ++x) image(x, 0) = static_cast<float>(x);
  const GreyWindow window = autoWindow(image);
  EXPECT_DOUBLE_EQ(window.lo, 1.0);    // 0.5 % of 200
  EXPECT_DOUBLE_EQ(window.hi, 199.0);  // 99.5 % of 200
  const GreyWindow constant = autoWindow(Image(3, 3, 7.0f));
  EXPECT_EQ(constant.lo, 6.5);
  EXPECT_EQ(constant.hi, 7.5);
  const GreyWindow none = autoWindow(Image(2, 2, std::numeric_limits<float>::quiet_NaN()));
  EXPECT_EQ(none.lo, 0.0);
  EXPECT_EQ(none.hi, 1.0);
}

TEST(PreviewPng, HeaderAndPixels) {
  TestFolder folder;
  Image image(37, 21);
  for (int y = 0; y < 21; ++y)
    for (int x = 0; x < 37; ++x) image(x, y) = static_cast<float>(x * 10 - y);
  const auto path = folder / "preview.png";
  writePreviewPng(path, image, 0.0, 255.0);
  const PngHeader header = readPngHeader(path);
  EXPECT_EQ(header.width, 37u);
  EXPECT_EQ(header.height, 21u);
  EXPECT_EQ(header.bit_depth, 8);
  EXPECT_EQ(header.colour_type, 0);
  const Decoded decoded = decodePng(path);
  ASSERT_EQ(decoded.channels, 1);
  for (int y = 0; y < 21; ++y)
    for (int x = 0; x < 37; ++x)
      ASSERT_EQ(*decoded.at(x, y), greyLevel(image(x, y), 0.0, 255.0)) << x << ", " << y;
  EXPECT_EQ(*decoded.at(3, 0), 30);
  EXPECT_EQ(*decoded.at(36, 0), 255);  // 360 clamped
  EXPECT_EQ(*decoded.at(0, 5), 0);     // -5 clamped
  EXPECT_EQ(folder.entries(), std::vector<std::string>{"preview.png"});
}

TEST(PreviewPng, AutoWindowSpansBlackToWhite) {
  TestFolder folder;
  Image image(50, 40);
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 50; ++x) image(x, y) = static_cast<float>(1000 + x + 50 * y);
  writePreviewPng(folder / "auto.png", image);
  const Decoded decoded = decodePng(folder / "auto.png");
  EXPECT_EQ(*decoded.at(0, 0), 0);
  EXPECT_EQ(*decoded.at(49, 39), 255);
  EXPECT_NEAR(*decoded.at(0, 20), 128, 1);
}

TEST(PreviewPng, Errors) {
  TestFolder folder;
  EXPECT_THROW(writePreviewPng(folder / "a.png", Image(2, 2), 1.0, 1.0), Error);
  EXPECT_THROW(
      writePreviewPng(folder / "a.png", Image(2, 2), 0.0, std::numeric_limits<double>::infinity()),
      Error);
  EXPECT_THROW(writePreviewPng(folder / "a.png", Image()), Error);
  EXPECT_THROW(writePreviewPng(folder / "missing" / "a.png", Image(2, 2)), Error);
  EXPECT_THROW(writeDifferencePng(folder / "d.png", Image(2, 2), 0.0), Error);
  EXPECT_THROW(writeDifferencePng(folder / "d.png", Image()), Error);
  EXPECT_TRUE(folder.entries().empty());
}

TEST(DivergingColor, WhiteAtZeroBlueAndRedAtTheEnds) {
  EXPECT_EQ(divergingColor(0.0), (Rgb8{255, 255, 255}));
  EXPECT_EQ(divergingColor(1.0), (Rgb8{103, 0, 31}));
  EXPECT_EQ(divergingColor(-1.0), (Rgb8{5, 48, 97}));
  EXPECT_EQ(divergingColor(7.0), divergingColor(1.0));
  EXPECT_EQ(divergingColor(-7.0), divergingColor(-1.0));
  EXPECT_EQ(divergingColor(std::numeric_limits<double>::quiet_NaN()), (Rgb8{0, 0, 0}));
  // Halfway between two stops: RdBu classes 9 and 10 (#b2182b, #67001f).
  EXPECT_EQ(divergingColor(0.9), (Rgb8{141, 12, 37}));
  // Positive is reddish, negative bluish, and both darken towards the ends.
  for (double t = 0.1; t <= 1.0; t += 0.1) {
    const Rgb8 red = divergingColor(t), blue = divergingColor(-t);
    EXPECT_GT(red.r, red.b) << t;
    EXPECT_GT(blue.b, blue.r) << t;
    const Rgb8 red_before = divergingColor(t - 0.1), blue_before = divergingColor(0.1 - t);
    EXPECT_LT(red.r + red.g + red.b, red_before.r + red_before.g + red_before.b) << t;
    EXPECT_LT(blue.r + blue.g + blue.b, blue_before.r + blue_before.g + blue_before.b) << t;
  }
}

TEST(DifferencePng, HeaderAndColours) {
  TestFolder folder;
  Image difference(3, 2, 0.0f);
  difference(0, 0) = -0.02f;  // the largest |value|: sets the default scale
  difference(1, 0) = 0.01f;
  difference(2, 0) = 0.02f;
  difference(0, 1) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(defaultDifferenceScale(difference), static_cast<double>(0.02f));
  const auto path = folder / "difference.png";
  writeDifferencePng(path, difference);
  const PngHeader header = readPngHeader(path);
  EXPECT_EQ(header.width, 3u);
  EXPECT_EQ(header.height, 2u);
  EXPECT_EQ(header.bit_depth, 8);
  EXPECT_EQ(header.colour_type, 2);
  const Decoded decoded = decodePng(path);
  ASSERT_EQ(decoded.channels, 3);
  const auto colour = [&](int x, int y) {
    const unsigned char* p = decoded.at(x, y);
    return Rgb8{p[0], p[1], p[2]};
  };
  EXPECT_EQ(colour(0, 0), divergingColor(-1.0));
  EXPECT_EQ(colour(1, 0), divergingColor(0.5));
  EXPECT_EQ(colour(2, 0), divergingColor(1.0));
  EXPECT_EQ(colour(1, 1), (Rgb8{255, 255, 255}));
  EXPECT_EQ(colour(0, 1), (Rgb8{0, 0, 0}));
  EXPECT_EQ(defaultDifferenceScale(Image(2, 2, 0.0f)), 1.0);
}

}  // namespace
}  // namespace xgauge
