// The exports: the .dfq read back by an independent reader (dfq_reader.h)
// gives every value, limit and time; the CSV has a row per part and
// dimension.
#include "xgauge/production/export.h"

#include "dfq_reader.h"
#include "xgauge/core/error.h"

#include <gtest/gtest.h>

#include <cmath>

namespace xgauge {
namespace {

std::vector<StoredPart> lot() {
  std::vector<StoredPart> parts;
  for (int k = 1; k <= 25; ++k) {
    StoredPart p;
    p.part = fmt::format("p{:04d}", k);
    p.part_index = k;
    p.acquired_at = fmt::format("2026-12-04T{:02d}:{:02d}:07Z", 6 + k / 60, k % 60);
    p.measured_at = "2026-12-04T12:00:00Z";
    p.status = k == 7 ? "not measured" : "measured";
    p.station = "s1";
    if (k != 7) {
      StoredDimension w{"width", 20.977 + std::sin(k) * 1e-3 / 3.0,
                        "mm",    0.004,
                        true,    false,
                        21.0,    20.95,
                        21.05,   "conforms"};
      StoredDimension a{"angle", 45.0 + k * 1e-4, "deg",        std::nullopt, false,
                        false,   std::nullopt,    std::nullopt, std::nullopt, ""};
      p.dimensions = {w, a};
    }
    parts.push_back(p);
  }
  return parts;
}

TEST(Export, DfqReadsBackEveryValueLimitAndTime) {
  const auto parts = lot();
  const std::string text = lotDfq({"L7", "prism_jaw", "Prism jaw, line 3"}, parts);
  const test::DfqFile dfq = test::readDfq(text);
  EXPECT_EQ(dfq.other.at(100), "2");
  EXPECT_EQ(dfq.part.at(1001), "prism_jaw");
  EXPECT_EQ(dfq.part.at(1002), "Prism jaw, line 3");
  ASSERT_EQ(dfq.characteristics.size(), 2u);
  const auto& width = dfq.characteristics.at(1);
  EXPECT_EQ(width.fields.at(2001), "width");
  EXPECT_EQ(std::stod(width.fields.at(2101)), 21.0);
  EXPECT_EQ(std::stod(width.fields.at(2110)), 20.95);
  EXPECT_EQ(std::stod(width.fields.at(2111)), 21.05);
  EXPECT_EQ(width.fields.at(2142), "mm");
  const auto& angle = dfq.characteristics.at(2);
  EXPECT_EQ(angle.fields.at(2142), "deg");
  EXPECT_FALSE(angle.fields.count(2110));  // no tolerance, no limits
  // 24 measured parts (p0007 was not measured), in order, exact.
  ASSERT_EQ(width.values.size(), 24u);
  ASSERT_EQ(angle.values.size(), 24u);
  size_t v = 0;
  for (const auto& p : parts) {
    if (p.status != "measured") continue;
    const auto& got = width.values[v];
    EXPECT_EQ(std::stod(got.fields.at(1)), p.dimensions[0].value) << p.part;  // bit for bit
    EXPECT_EQ(std::stod(angle.values[v].fields.at(1)), p.dimensions[1].value) << p.part;
    // DD.MM.YYYY/HH:MM:SS of the acquisition time.
    const std::string& iso = p.acquired_at;
    EXPECT_EQ(got.fields.at(4), iso.substr(8, 2) + "." + iso.substr(5, 2) + "." + iso.substr(0, 4) +
                                    "/" + iso.substr(11, 8));
    EXPECT_EQ(got.fields.at(14), p.part);
    EXPECT_EQ(got.fields.at(6), "L7");
    ++v;
  }
}

TEST(Export, AqdefTimeRefusesOtherForms) {
  EXPECT_EQ(aqdefTime("2026-01-31T23:59:58Z"), "31.01.2026/23:59:58");
  EXPECT_THROW(aqdefTime("2026-01-31 23:59:58"), Error);
}

TEST(Export, CsvHasARowPerPartAndDimension) {
  const std::string csv = lotCsv({"L,7", "prism_jaw", ""}, lot());
  size_t rows = 0;
  for (char c : csv) rows += c == '\n';
  EXPECT_EQ(rows, 1u + 24u * 2u + 1u);  // header, 24 parts x 2, the not-measured part's row
  EXPECT_NE(csv.find("\"L,7\",p0001,1,"), std::string::npos) << csv.substr(0, 300);
  EXPECT_NE(csv.find(",not measured,"), std::string::npos);
}

}  // namespace
}  // namespace xgauge
