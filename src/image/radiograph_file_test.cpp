#include "xgauge/image/radiograph_file.h"

#include "test_folder.h"
#include "xgauge/core/digest.h"
#include "xgauge/image/diconde.h"
#include "xgauge/image/nxtomo.h"
#include "xgauge/image/raw_file.h"

#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcrleerg.h>
#include <gtest/gtest.h>
#include <hdf5.h>
#include <tiffio.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace xgauge {
namespace {

namespace fs = std::filesystem;

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

std::string messageOf(const fs::path& path) {
  try {
    readRadiograph(path);
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

void writeText(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

void writeBytes(const fs::path& path, const std::vector<unsigned char>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

std::string readBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// A 37 x 23 image (odd sizes catch row-stride mistakes): whole numbers over
// the full 16-bit range, or floats of every magnitude and sign (subnormals
// included), which only an exact round trip keeps bit for bit.
Image testImage(TiffFormat format, uint32_t seed) {
  std::mt19937 rng(seed);
  Image image(37, 23);
  for (float& v : image.pixels()) {
    if (format == TiffFormat::kUInt16) {
      v = static_cast<float>(rng() % 65536u);
    } else {
      uint32_t bits = rng();
      // Keep them finite: an exponent of all ones is NaN or infinity.
      if (((bits >> 23) & 0xffu) == 0xffu) bits &= ~(1u << 23);
      v = std::bit_cast<float>(bits);
    }
  }
  image(0, 0) = 0.0f;
  image(36, 22) = format == TiffFormat::kUInt16 ? 65535.0f : -1.5f;
  return image;
}

bool bitIdentical(const Image& a, const Image& b) {
  return a.width() == b.width() && a.height() == b.height() &&
         std::memcmp(a.pixels().data(), b.pixels().data(), a.pixels().size_bytes()) == 0;
}

// Acceptance (issue 48): a radiograph written as raw + sidecar, NXtomo and
// DICONDE reads back equal to the TIFF bit for bit, for uint16 and float32.
TEST(RadiographFile, EveryFormatReadsBackEqualToTheTiffBitForBit) {
  TestFolder folder;
  for (const TiffFormat format : {TiffFormat::kUInt16, TiffFormat::kFloat32}) {
    const char* kind = format == TiffFormat::kUInt16 ? "u16" : "f32";
    SCOPED_TRACE(kind);
    const Image image = testImage(format, format == TiffFormat::kUInt16 ? 1u : 2u);
    const fs::path tiff = folder / fmt::format("{}.tif", kind);
    writeRadiograph(tiff, image, format);
    const RadiographFile from_tiff = readRadiograph(tiff);
    ASSERT_EQ(from_tiff.format, RadiographFormat::kTiff);
    ASSERT_TRUE(bitIdentical(from_tiff.image, image));
    for (const std::string extension : {".raw", ".nxs", ".dcm"}) {
      SCOPED_TRACE(extension);
      const fs::path path = folder / (std::string(kind) + extension);
      writeRadiograph(path, image, format);
      std::string sha;
      const RadiographFile read = readRadiograph(path, &sha);
      EXPECT_TRUE(bitIdentical(read.image, from_tiff.image));
      EXPECT_EQ(read.frames, 1);
      EXPECT_EQ(read.format, extension == ".raw"   ? RadiographFormat::kRaw
                             : extension == ".nxs" ? RadiographFormat::kNxTomo
                                                   : RadiographFormat::kDiconde);
      // The digest is of the file's bytes (raw: followed by the sidecar's).
      const std::string bytes =
          readBytes(path) + (extension == ".raw"
                                 ? readBytes(folder / (kind + std::string(".raw.json")))
                                 : std::string());
      EXPECT_EQ(sha, sha256Hex(bytes));
      // The same image gives the same bytes.
      const std::string first = readBytes(path);
      writeRadiograph(path, image, format);
      EXPECT_EQ(readBytes(path), first);
    }
  }
  // A file named for another format is read as what it is.
  fs::copy_file(folder / "u16.dcm", folder / "misnamed.tif");
  EXPECT_EQ(readRadiograph(folder / "misnamed.tif").format, RadiographFormat::kDiconde);
  // Nothing but the outputs is left behind (no temporaries).
  EXPECT_EQ(folder.entries().size(), 2u * 5u + 1u);
}

// A multi-page TIFF of `pages` frames, 8-bit or 32-bit float.
void writePages(const fs::path& path, const std::vector<Image>& pages,
                const std::vector<int>& widths = {}) {
  TIFF* tif = TIFFOpen(path.c_str(), "w");
  ASSERT_NE(tif, nullptr);
  for (size_t p = 0; p < pages.size(); ++p) {
    const Image& page = pages[p];
    const int width = widths.empty() ? page.width() : widths[p];
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, width);
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, page.height());
    TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, 32);
    TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_IEEEFP);
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, 1);
    TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
    TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, 8);
    std::vector<float> row(static_cast<size_t>(width));
    for (int y = 0; y < page.height(); ++y) {
      std::copy_n(page.row(y), std::min(width, page.width()), row.begin());
      ASSERT_EQ(TIFFWriteScanline(tif, row.data(), static_cast<uint32_t>(y), 0), 1);
    }
    ASSERT_EQ(TIFFWriteDirectory(tif), 1);
  }
  TIFFClose(tif);
}

// The noise of one pixel from horizontal neighbour differences, as the
// measurement's misfit check estimates it (measure/checks.cpp:
// 1.4826 median |d| / sqrt 2).
double neighbourNoise(const Image& image) {
  std::vector<double> d;
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x + 1 < image.width(); ++x)
      d.push_back(
          std::abs(static_cast<double>(image(x + 1, y)) - static_cast<double>(image(x, y))));
  std::nth_element(d.begin(), d.begin() + static_cast<ptrdiff_t>(d.size() / 2), d.end());
  return 1.4826 * d[d.size() / 2] / std::sqrt(2.0);
}

TEST(RadiographFile, MultiPageTiffIsTheMeanOfItsPagesWithHalfTheNoiseOfFour) {
  TestFolder folder;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 20.0);
  std::vector<Image> pages;
  for (int p = 0; p < 4; ++p) {
    Image page(128, 96);
    for (int y = 0; y < page.height(); ++y)
      for (int x = 0; x < page.width(); ++x)
        page(x, y) = static_cast<float>(1000.0 + 2.0 * x + noise(rng));  // a ramp plus noise
    pages.push_back(std::move(page));
  }
  writePages(folder / "four.tif", pages);
  writePages(folder / "one.tif", {pages[0]});
  const RadiographFile four = readRadiograph(folder / "four.tif");
  const RadiographFile one = readRadiograph(folder / "one.tif");
  EXPECT_EQ(four.frames, 4);
  EXPECT_EQ(one.frames, 1);
  EXPECT_TRUE(bitIdentical(one.image, pages[0]));
  // The mean, summed in double and rounded once.
  for (int y = 0; y < 96; y += 13)
    for (int x = 0; x < 128; x += 11) {
      double sum = 0.0;
      for (const Image& page : pages) sum += static_cast<double>(page(x, y));
      EXPECT_EQ(four.image(x, y), static_cast<float>(sum / 4.0)) << x << ", " << y;
    }
  // Averaging 4 frames leaves half the noise, and the image-based estimate
  // sees it: nothing else needs to know the frame count.
  const double ratio = neighbourNoise(four.image) / neighbourNoise(one.image);
  EXPECT_NEAR(ratio, 0.5, 0.05);
  EXPECT_NEAR(neighbourNoise(one.image), 20.0, 1.5);
}

TEST(RadiographFile, MultiPageTiffOfDifferentPagesIsRefused) {
  TestFolder folder;
  const Image page(16, 4, 100.0f);
  writePages(folder / "pages.tif", {page, page, page}, {16, 16, 12});
  const std::string message = messageOf(folder / "pages.tif");
  EXPECT_TRUE(contains(message, "pages.tif")) << message;
  EXPECT_TRUE(contains(message, "page 3 is 12x4 pixels of 32-bit float but page 1 is 16x4"))
      << message;
}

TEST(RadiographFile, MultiPageTiffNaNIsNamedWithItsPage) {
  TestFolder folder;
  Image bad(8, 2, 1.0f);
  bad(5, 1) = std::numeric_limits<float>::quiet_NaN();
  writePages(folder / "pages.tif", {Image(8, 2, 1.0f), bad});
  const std::string message = messageOf(folder / "pages.tif");
  EXPECT_TRUE(contains(message, "pixel (5, 1) of page 2 is nan")) << message;
}

TEST(RadiographFile, MultiPageMemoryLimitCountsTheSum) {
  TestFolder folder;
  writePages(folder / "pages.tif", {Image(100, 100, 1.0f), Image(100, 100, 3.0f)});
  const uint64_t before = tiffMemoryLimit();
  // Enough for one page and a strip, not for the running sum of two.
  setTiffMemoryLimit(100 * 100 * 4 + 100 * 8 * 4 + 1000);
  const std::string message = messageOf(folder / "pages.tif");
  setTiffMemoryLimit(before);
  EXPECT_TRUE(contains(message, "declares 2 frames of 100x100 pixels")) << message;
  EXPECT_EQ(readRadiograph(folder / "pages.tif").image(3, 3), 2.0f);
}

// Raw + sidecar ----------------------------------------------------------

TEST(RawFile, IniSidecarBigEndianWithOffsetAndFramesIsAveraged) {
  TestFolder folder;
  // 3 x 2 uint16 big-endian, after a 5-byte header, 2 frames.
  std::vector<unsigned char> bytes = {'H', 'E', 'A', 'D', '!'};
  for (int frame = 0; frame < 2; ++frame)
    for (int i = 0; i < 6; ++i) {
      const int value = 1000 * (i + 1) + frame * 10;  // frames differ by 10
      bytes.push_back(static_cast<unsigned char>(value >> 8));
      bytes.push_back(static_cast<unsigned char>(value & 0xff));
    }
  writeBytes(folder / "shot.raw", bytes);
  writeText(folder / "shot.raw.ini",
            "; exported by the cabinet\n[raw]\nwidth = 3\nheight = 2\ntype = uint16\n"
            "byte_order = big\noffset = 5\nframes = 2\n");
  std::string sha;
  const RadiographFile read = readRadiograph(folder / "shot.raw", &sha);
  EXPECT_EQ(read.format, RadiographFormat::kRaw);
  EXPECT_EQ(read.frames, 2);
  ASSERT_EQ(read.image.width(), 3);
  ASSERT_EQ(read.image.height(), 2);
  EXPECT_EQ(read.image(0, 0), 1005.0f);
  EXPECT_EQ(read.image(2, 1), 6005.0f);
  EXPECT_EQ(sha, sha256Hex(readBytes(folder / "shot.raw") + readBytes(folder / "shot.raw.ini")));
}

TEST(RawFile, HostileSidecarsAndFilesAreRefusedNamingTheFileAndKey) {
  TestFolder folder;
  const fs::path raw = folder / "r.raw";
  writeBytes(raw, std::vector<unsigned char>(4 * 3 * 4, 0));  // 4 x 3 float32, zeros
  const auto refused = [&](const std::string& sidecar_name, const std::string& sidecar,
                           const std::string& expected) {
    SCOPED_TRACE(sidecar);
    writeText(folder / sidecar_name, sidecar);
    const std::string message = messageOf(raw);
    EXPECT_TRUE(contains(message, expected)) << message;
    fs::remove(folder / sidecar_name);
  };
  const std::string ok = R"("width": 4, "height": 3, "type": "float32", "byte_order": "little")";
  writeText(folder / "r.raw.json", "{" + ok + "}");
  EXPECT_EQ(readRadiograph(raw).image.width(), 4);
  fs::remove(folder / "r.raw.json");

  EXPECT_TRUE(contains(messageOf(raw), "no sidecar r.raw.json or r.raw.ini")) << messageOf(raw);
  refused("r.raw.json", "{" + ok + R"(, "widht": 4})",
          "unknown key 'widht'; did you mean 'width'?");
  refused("r.raw.json", "{" + ok + R"(, "frame": 1})", "did you mean 'frames'?");
  refused("r.raw.ini", "[raw]\nwidth=4\nheight=3\ntype=float32\nbyte_ordre=little\n",
          "r.raw.ini:5: unknown key 'byte_ordre'; did you mean 'byte_order'?");
  refused("r.raw.ini", "[raw]\nwidth=4\nheight=3\ntype=float16\nbyte_order=little\n",
          "r.raw.ini:4: type: expected uint8, uint16, uint32, float32 or float64, got 'float16'");
  refused("r.raw.json", R"({"width": 4, "height": 3, "type": "float32"})",
          "missing key 'byte_order'");
  refused("r.raw.json", R"({"width": 4, "height": 3, "type": "int16", "byte_order": "little"})",
          "/type: expected uint8");
  refused("r.raw.json", R"({"width": 5, "height": 3, "type": "float32", "byte_order": "little"})",
          "r.raw: is 48 bytes long but its sidecar r.raw.json declares 60 bytes");
  refused("r.raw.json",
          R"({"width": 4, "height": 3, "type": "float32", "byte_order": "little", "offset": 4})",
          "declares 52 bytes");
  // A huge declared size: refused by length before anything is allocated.
  refused("r.raw.json",
          R"({"width": 2147483647, "height": 2147483647, "type": "float64", "byte_order": "big",
              "frames": 1048576})",
          "declares more than 2^64 bytes");
  writeText(folder / "r.raw.json", "{" + ok + "}");
  writeText(folder / "r.raw.ini", "[raw]\n");
  EXPECT_TRUE(contains(messageOf(raw), "two sidecars")) << messageOf(raw);
  fs::remove(folder / "r.raw.ini");

  // A NaN is named by its pixel and frame.
  std::vector<unsigned char> bytes(4 * 3 * 4 * 2, 0);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(bytes.data() + 4 * 3 * 4 + (1 * 4 + 2) * 4, &nan, 4);
  writeBytes(raw, bytes);
  writeText(folder / "r.raw.json", R"({"width": 4, "height": 3, "type": "float32",
                                       "byte_order": "little", "frames": 2})");
  EXPECT_TRUE(contains(messageOf(raw), "r.raw: pixel (2, 1) of frame 2 is nan")) << messageOf(raw);

  // The memory limit, before allocating: 2 frames of 4 x 3 need 4 * 3 * 16
  // bytes plus a row.
  const uint64_t before = tiffMemoryLimit();
  setTiffMemoryLimit(4 * 3 * 16);
  const std::string message = messageOf(raw);
  setTiffMemoryLimit(before);
  EXPECT_TRUE(contains(message, "declares 2 frames of 4x3 pixels")) << message;
}

// NXtomo ------------------------------------------------------------------

TEST(NxTomo, SelectorsPickProjectionsDarksAndFlats) {
  TestFolder folder;
  const Image dark1(6, 4, 100.0f), dark2(6, 4, 104.0f), flat(6, 4, 3000.0f);
  Image p0 = testImage(TiffFormat::kUInt16, 3).crop({0, 0, 6, 4});
  Image p1 = testImage(TiffFormat::kUInt16, 4).crop({0, 0, 6, 4});
  const std::vector<NxTomoFrame> frames = {
      {&dark1, 2, 0.0}, {&p0, 0, 0.0}, {&flat, 1, 0.0}, {&p1, 0, 7.5}, {&dark2, 2, 0.0}};
  const fs::path scan = folder / "scan.nxs";
  writeNxTomo(scan, frames, TiffFormat::kUInt16);
  const auto read = [&](const std::string& selector) {
    return readRadiograph(scan.string() + "#" + selector);
  };
  EXPECT_TRUE(bitIdentical(read("projection=0").image, p0));
  EXPECT_TRUE(bitIdentical(read("projection=1").image, p1));
  EXPECT_TRUE(bitIdentical(read("angle=7.5").image, p1));
  const RadiographFile dark = read("dark");
  EXPECT_EQ(dark.frames, 2);
  EXPECT_EQ(dark.image(5, 3), 102.0f);
  EXPECT_EQ(read("flat").image(0, 0), 3000.0f);
  // Naming the file and what it holds.
  const auto message = [&](const std::string& path) { return messageOf(path); };
  EXPECT_TRUE(contains(message(scan.string()),
                       "the file holds 2 projection(s), 1 flat(s) and 2 dark(s): name one"))
      << message(scan.string());
  EXPECT_TRUE(
      contains(message(scan.string() + "#projection=2"), "scan.nxs#projection=2: #projection=2"))
      << message(scan.string() + "#projection=2");
  EXPECT_TRUE(contains(message(scan.string() + "#angle=3"), "no projection at rotation angle 3"));
  EXPECT_TRUE(contains(message(scan.string() + "#darks"), "unknown frame selector '#darks'"));
  EXPECT_TRUE(contains(message(folder.path().string() + "/nothing.nxs#dark"), "does not exist"));
  // A selector on a file that is not NXtomo.
  writeTiff(folder / "a.tif", p0, TiffFormat::kUInt16);
  EXPECT_TRUE(contains(message((folder / "a.tif").string() + "#dark"), "is not one"));
  // The memory limit: one frame and its buffer fit, two (averaged) do not.
  const uint64_t before = tiffMemoryLimit();
  setTiffMemoryLimit(6 * 4 * 4 + 6 * 4 * 2);
  EXPECT_TRUE(bitIdentical(read("projection=0").image, p0));
  const std::string limited = message(scan.string() + "#dark");
  setTiffMemoryLimit(before);
  EXPECT_TRUE(contains(limited, "declares 2 frames of 6x4 pixels")) << limited;
}

// An HDF5 file holding only some of NXtomo's datasets.
void writePartialNxTomo(const fs::path& path, bool with_image_key, hsize_t key_length,
                        hsize_t frames, hsize_t rows, hsize_t columns, bool allocate) {
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  const hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
  H5Pset_create_intermediate_group(lcpl, 1);
  const hsize_t dims[3] = {frames, rows, columns};
  const hid_t space = H5Screate_simple(3, dims, nullptr);
  const hid_t data =
      H5Dcreate2(file, "/entry/data/data", H5T_STD_U16LE, space, lcpl, H5P_DEFAULT, H5P_DEFAULT);
  if (allocate) {
    std::vector<uint16_t> zeros(frames * rows * columns, 7);
    H5Dwrite(data, H5T_NATIVE_UINT16, H5S_ALL, H5S_ALL, H5P_DEFAULT, zeros.data());
  }
  if (with_image_key) {
    const hid_t key_space = H5Screate_simple(1, &key_length, nullptr);
    const hid_t keys = H5Dcreate2(file, "/entry/instrument/detector/image_key", H5T_STD_I32LE,
                                  key_space, lcpl, H5P_DEFAULT, H5P_DEFAULT);
    std::vector<int> zeros(key_length, 0);
    H5Dwrite(keys, H5T_NATIVE_INT, H5S_ALL, H5S_ALL, H5P_DEFAULT, zeros.data());
    H5Dclose(keys);
    H5Sclose(key_space);
  }
  H5Dclose(data);
  H5Sclose(space);
  H5Pclose(lcpl);
  H5Fclose(file);
}

TEST(NxTomo, HostileFilesAreRefusedNamingTheDataset) {
  // One whose header declares a 2 GB metadata block: refused, and the
  // reading process may not grow by more than the image cap to find out.
  const std::filesystem::path greedy =
      std::filesystem::path(XGAUGE_SOURCE_DIR) /
      "fuzz/known/fuzz_nxtomo/libhdf5-1.10.8-2gb-metadata-alloc.nxs";
  std::string greedy_message;
  try {
    readNxTomo(greedy, "");
  } catch (const Error& e) {
    greedy_message = e.what();
  }
  EXPECT_TRUE(contains(greedy_message, "libhdf5-1.10.8-2gb-metadata-alloc.nxs: "))
      << greedy_message;
  TestFolder folder;
  writePartialNxTomo(folder / "nokey.nxs", false, 0, 1, 4, 4, true);
  std::string message = messageOf(folder / "nokey.nxs");
  EXPECT_TRUE(contains(message, "nokey.nxs: no dataset /entry/instrument/detector/image_key"))
      << message;
  writePartialNxTomo(folder / "short.nxs", true, 2, 3, 4, 4, true);
  message = messageOf(folder / "short.nxs");
  EXPECT_TRUE(contains(message, "image_key holds 2 values but /entry/data/data holds 3 frames"))
      << message;
  // Declared but never written: 1000 frames of 4096^2 in a file of a few KiB.
  writePartialNxTomo(folder / "empty.nxs", true, 1000, 1000, 4096, 4096, false);
  message = messageOf(folder / "empty.nxs");
  EXPECT_TRUE(contains(message, "stores 0 bytes: it was never written")) << message;
  // Truncated: the HDF5 library's own complaint, named.
  const std::string whole = readBytes(folder / "short.nxs");
  writeText(folder / "cut.nxs", whole.substr(0, whole.size() / 2));
  message = messageOf(folder / "cut.nxs");
  EXPECT_TRUE(contains(message, "cut.nxs: ")) << message;
  // No file above; the selector is part of the location.
  writeText(folder / "fake.nxs", "\x89HDF\r\n\x1a\n and nothing else");
  message = messageOf(folder / "fake.nxs");
  EXPECT_TRUE(contains(message, "fake.nxs: ")) << message;
}

// A file on which libhdf5 1.10.8 itself crashes (a null write in
// H5G__stab_lookup, found by scripts/fuzz.sh): read in a child process, the
// crash is this file's error, and the next read works.
TEST(NxTomo, AFileThatCrashesLibhdf5IsAnErrorNotACrash) {
  const std::filesystem::path crafted = std::filesystem::path(XGAUGE_SOURCE_DIR) /
                                        "fuzz/known/fuzz_nxtomo/libhdf5-1.10.8-segv-local-heap.nxs";
  ASSERT_TRUE(std::filesystem::exists(crafted));
  for (const char* selector : {"", "dark", "flat", "projection=0", "angle=0"}) {
    std::string message;
    try {
      readNxTomo(crafted, selector);
    } catch (const Error& e) {
      message = e.what();
    }
    EXPECT_TRUE(contains(message, "libhdf5-1.10.8-segv-local-heap.nxs"))
        << selector << ": " << message;
  }
  TestFolder folder;
  writePartialNxTomo(folder / "nokey.nxs", false, 0, 1, 4, 4, true);
  EXPECT_TRUE(contains(messageOf(folder / "nokey.nxs"), "no dataset"));
}

// DICONDE -----------------------------------------------------------------

TEST(Diconde, RescaleFramesAndCompressionAreHandled) {
  TestFolder folder;
  const Image image = testImage(TiffFormat::kUInt16, 5).crop({0, 0, 5, 3});
  const fs::path plain = folder / "plain.dcm";
  writeDiconde(plain, image, TiffFormat::kUInt16);

  // Rescale slope and intercept apply: value = 0.5 stored - 10.
  {
    DcmFileFormat file;
    ASSERT_TRUE(file.loadFile(plain.c_str()).good());
    file.getDataset()->putAndInsertString(DCM_RescaleSlope, "0.5");
    file.getDataset()->putAndInsertString(DCM_RescaleIntercept, "-10");
    ASSERT_TRUE(file.saveFile((folder / "rescaled.dcm").c_str(), EXS_LittleEndianExplicit).good());
  }
  const Image rescaled = readRadiograph(folder / "rescaled.dcm").image;
  EXPECT_EQ(rescaled(2, 1), static_cast<float>(0.5 * static_cast<double>(image(2, 1)) - 10.0));

  // Two frames are averaged; big-endian transfer syntax reads the same.
  {
    DcmFileFormat file;
    ASSERT_TRUE(file.loadFile(plain.c_str()).good());
    std::vector<Uint16> two(30);
    for (size_t i = 0; i < 15; ++i) {
      two[i] = 100;
      two[15 + i] = 300;
    }
    file.getDataset()->putAndInsertUint16Array(DCM_PixelData, two.data(), two.size());
    file.getDataset()->putAndInsertString(DCM_NumberOfFrames, "2");
    ASSERT_TRUE(file.saveFile((folder / "two.dcm").c_str(), EXS_BigEndianExplicit).good());
  }
  const RadiographFile two = readRadiograph(folder / "two.dcm");
  EXPECT_EQ(two.frames, 2);
  EXPECT_EQ(two.image(4, 2), 200.0f);

  // A compressed transfer syntax is refused, naming it.
  {
    DcmRLEEncoderRegistration::registerCodecs();
    DcmFileFormat file;
    ASSERT_TRUE(file.loadFile(plain.c_str()).good());
    ASSERT_TRUE(file.getDataset()->chooseRepresentation(EXS_RLELossless, nullptr).good());
    ASSERT_TRUE(file.saveFile((folder / "rle.dcm").c_str(), EXS_RLELossless).good());
    DcmRLEEncoderRegistration::cleanup();
  }
  std::string message = messageOf(folder / "rle.dcm");
  EXPECT_TRUE(
      contains(message, "rle.dcm: the transfer syntax is RLE Lossless (1.2.840.10008.1.2.5)"))
      << message;

  // Signed samples and short Pixel Data are refused, naming the tag.
  {
    DcmFileFormat file;
    ASSERT_TRUE(file.loadFile(plain.c_str()).good());
    file.getDataset()->putAndInsertUint16(DCM_PixelRepresentation, 1);
    ASSERT_TRUE(file.saveFile((folder / "signed.dcm").c_str(), EXS_LittleEndianExplicit).good());
    file.getDataset()->putAndInsertUint16(DCM_PixelRepresentation, 0);
    file.getDataset()->putAndInsertUint16(DCM_Rows, 300);
    ASSERT_TRUE(file.saveFile((folder / "short.dcm").c_str(), EXS_LittleEndianExplicit).good());
  }
  message = messageOf(folder / "signed.dcm");
  EXPECT_TRUE(contains(message, "(0028,0103) PixelRepresentation = 1: signed")) << message;
  message = messageOf(folder / "short.dcm");
  EXPECT_TRUE(contains(message, "(7FE0,0010) PixelData holds 15 samples but 5x300 pixels"))
      << message;

  // A value declared longer than the file: refused before DCMTK allocates it.
  std::string whole = readBytes(plain);
  const size_t pixel_data = whole.rfind(std::string("\xe0\x7f\x10\x00OW\0\0", 8));
  ASSERT_NE(pixel_data, std::string::npos);
  std::string huge = whole;
  huge.replace(pixel_data + 8, 4, std::string("\x00\x00\x00\xb0", 4));  // 2.9 GB
  writeText(folder / "huge.dcm", huge);
  message = messageOf(folder / "huge.dcm");
  EXPECT_TRUE(contains(message, "huge.dcm: element (7FE0,0010) at byte")) << message;
  EXPECT_TRUE(contains(message, "declares 2952790016 bytes but the file has 30 left")) << message;

  // Truncated files: refused with a reason, no crash.
  for (const size_t length : {size_t{10}, size_t{140}, whole.size() / 2, whole.size() - 3}) {
    writeText(folder / "cut.dcm", whole.substr(0, length));
    message = messageOf(folder / "cut.dcm");
    EXPECT_TRUE(contains(message, "cut.dcm: ")) << length << ": " << message;
  }
}

}  // namespace
}  // namespace xgauge
