// The exports: the .dfq read back by an independent reader (dfq_reader.h)
// gives every value, limit and time; the CSV has a row per part and
// dimension.
#include "xgauge/production/export.h"

#include "dfq_reader.h"
#include "xgauge/core/error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <utility>

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

// Every field the writer wrote is one of AQDEF's, within its length and
// of its type (the reader lists any that is not).
void expectOnlyAqdefFields(const test::DfqFile& dfq) {
  EXPECT_TRUE(dfq.problems.empty()) << ::testing::PrintToString(dfq.problems);
}

TEST(Export, DfqReadsBackEveryValueLimitAndTime) {
  const auto parts = lot();
  const std::string text = lotDfq({"L7", "prism_jaw", "Prism jaw, line 3"}, parts);
  const test::DfqFile dfq = test::readDfq(text);
  expectOnlyAqdefFields(dfq);
  EXPECT_EQ(dfq.other.at(100), "2");
  EXPECT_EQ(dfq.part.at(1001), "prism_jaw");
  EXPECT_EQ(dfq.part.at(1002), "Prism jaw, line 3");
  ASSERT_EQ(dfq.characteristics.size(), 2u);
  const auto& width = dfq.characteristics.at(1);
  EXPECT_EQ(width.fields.at(2001), "width");
  EXPECT_EQ(width.fields.at(2142), "mm");
  const auto& angle = dfq.characteristics.at(2);
  EXPECT_EQ(angle.fields.at(2142), "deg");
  EXPECT_FALSE(angle.fields.count(2110));  // no tolerance, no limits
  // 24 measured parts (p0007 was not measured), in order.
  ASSERT_EQ(width.values.size(), 24u);
  ASSERT_EQ(angle.values.size(), 24u);
  size_t v = 0;
  for (const auto& p : parts) {
    if (p.status != "measured") continue;
    const auto& got = width.values[v];
    // DD.MM.YYYY/HH:MM:SS of the acquisition time.
    const std::string& iso = p.acquired_at;
    EXPECT_EQ(got.fields.at(4), iso.substr(8, 2) + "." + iso.substr(5, 2) + "." + iso.substr(0, 4) +
                                    "/" + iso.substr(11, 8));
    EXPECT_EQ(got.fields.at(14), p.part);
    EXPECT_EQ(angle.values[v].fields.at(14), p.part);
    ++v;
  }
}

// A lot with the plan's limits as doubles carry them (20.1 - 0.02 is
// 20.080000000000002): width U 0.004 mm, gap U 0.002 mm, angle without U.
std::vector<StoredPart> lotWithNoisyLimits() {
  auto parts = lot();
  for (auto& p : parts) {
    if (p.dimensions.empty()) continue;
    StoredDimension gap{"gap",       20.1 + std::cos(p.part_index) * 3e-3,
                        "mm",        0.002,
                        true,        false,
                        20.1,        20.1 - 0.02,
                        20.1 + 0.02, "conforms"};
    p.dimensions.push_back(gap);
  }
  return parts;
}

// The fields: the lot in K0006 (batch number) and nowhere else,
// K0006 within 14 characters, the limits the plan's at the declared
// decimals, every value with exactly the declared decimals and within half
// a last digit (and U/20) of the stored value.
TEST(Export, DfqFieldsAsAqdefDefinesThem) {
  const auto parts = lotWithNoisyLimits();
  ASSERT_EQ(fmt::format("{}", parts[0].dimensions[2].lower_limit.value()), "20.080000000000002");
  const std::string lot_name = "LOT-2026-1204";  // 13 characters
  const test::DfqFile dfq = test::readDfq(lotDfq({lot_name, "prism_jaw", ""}, parts));
  expectOnlyAqdefFields(dfq);
  ASSERT_EQ(dfq.characteristics.size(), 3u);

  // The lot: K0006 of every value, no part field (K1086 is the work cycle).
  EXPECT_FALSE(dfq.part.count(1086));
  for (const auto& [number, text] : dfq.part) EXPECT_NE(text, lot_name) << "K" << number;
  size_t values = 0;
  for (const auto& [i, c] : dfq.characteristics) {
    for (const auto& [number, text] : c.fields) EXPECT_NE(text, lot_name) << "K" << number;
    for (const auto& value : c.values) {
      EXPECT_EQ(value.fields.at(6), lot_name);
      EXPECT_LE(test::dfqCharacters(value.fields.at(6)), 14u);
      ++values;
    }
  }
  EXPECT_EQ(values, 24u * 3u);

  // K1002 is filled by default, naming the part number and the lot.
  const std::string& description = dfq.part.at(1002);
  EXPECT_NE(description.find("prism_jaw"), std::string::npos) << description;
  EXPECT_NE(description.find(lot_name), std::string::npos) << description;

  // Declared decimals: width U = 0.004 -> 4, gap U = 0.002 -> 4 (0.001
  // would be half of U), angle without U -> 6.
  const auto& width = dfq.characteristics.at(1);
  const auto& angle = dfq.characteristics.at(2);
  const auto& gap = dfq.characteristics.at(3);
  EXPECT_EQ(width.fields.at(2022), "4");
  EXPECT_EQ(angle.fields.at(2022), "6");
  EXPECT_EQ(gap.fields.at(2022), "4");
  EXPECT_EQ(width.fields.at(2101), "21.0000");
  EXPECT_EQ(width.fields.at(2110), "20.9500");
  EXPECT_EQ(width.fields.at(2111), "21.0500");
  EXPECT_EQ(gap.fields.at(2101), "20.1000");
  EXPECT_EQ(gap.fields.at(2110), "20.0800");
  EXPECT_EQ(gap.fields.at(2111), "20.1200");

  // Every limit and value against the plan and the store, characteristic by
  // characteristic: exactly the declared decimals, within half a last digit.
  const StoredPart& first = parts.front();
  for (const auto& [i, c] : dfq.characteristics) {
    const int decimals = std::stoi(c.fields.at(2022));
    const double half_digit = 0.5 * std::pow(10.0, -decimals) * (1.0 + 1e-9);
    const StoredDimension& plan = first.dimensions.at(static_cast<size_t>(i - 1));
    ASSERT_EQ(c.fields.at(2001), plan.name);
    for (const auto& [number, limit] :
         {std::pair{2101, plan.nominal}, std::pair{2110, plan.lower_limit},
          std::pair{2111, plan.upper_limit}}) {
      ASSERT_EQ(c.fields.count(number), limit ? 1u : 0u) << plan.name << " K" << number;
      if (!limit) continue;
      const std::string& text = c.fields.at(number);
      EXPECT_EQ(test::dfqDecimals(text), decimals) << plan.name << " K" << number << " " << text;
      EXPECT_LE(std::abs(std::stod(text) - *limit), 1e-12) << plan.name << " K" << number;
    }
    size_t v = 0;
    for (const auto& p : parts) {
      if (p.status != "measured") continue;
      const StoredDimension& d = p.dimensions.at(static_cast<size_t>(i - 1));
      const std::string& text = c.values.at(v++).fields.at(1);
      EXPECT_EQ(test::dfqDecimals(text), decimals) << p.part << " " << d.name << " " << text;
      EXPECT_LE(std::abs(std::stod(text) - d.value), half_digit) << p.part << " " << d.name;
      if (d.expanded_uncertainty) {
        EXPECT_LE(std::abs(std::stod(text) - d.value), *d.expanded_uncertainty / 20.0)
            << p.part << " " << d.name;
      }
    }
  }
}

// The decimals follow U (the fewest with a last digit <= U/10) unless the
// plan's limits need more.
int declaredDecimals(std::optional<double> u, std::optional<double> lsl = std::nullopt,
                     std::optional<double> usl = std::nullopt) {
  StoredPart p;
  p.part = "p1";
  p.acquired_at = "2026-12-04T06:00:00Z";
  p.status = "measured";
  p.dimensions.push_back({"d", 12.3456789, "mm", u, true, false,
                          lsl ? std::optional<double>(21.0) : std::nullopt, lsl, usl, ""});
  const test::DfqFile dfq = test::readDfq(lotDfq({"L1", "part", ""}, {p}));
  EXPECT_TRUE(dfq.problems.empty()) << ::testing::PrintToString(dfq.problems);
  const auto& c = dfq.characteristics.at(1);
  const int decimals = std::stoi(c.fields.at(2022));
  EXPECT_EQ(test::dfqDecimals(c.values.at(0).fields.at(1)), decimals);
  return decimals;
}

TEST(Export, DfqDecimalsFollowTheUncertainty) {
  EXPECT_EQ(declaredDecimals(0.004), 4);
  EXPECT_EQ(declaredDecimals(0.0042), 4);
  EXPECT_EQ(declaredDecimals(0.01), 3);
  EXPECT_EQ(declaredDecimals(0.02), 3);
  EXPECT_EQ(declaredDecimals(0.0004), 5);
  EXPECT_EQ(declaredDecimals(0.3), 2);
  EXPECT_EQ(declaredDecimals(5.0), 1);
  EXPECT_EQ(declaredDecimals(std::nullopt), 6);
  EXPECT_EQ(declaredDecimals(0.0), 6);  // no usable U
  // U = 0.05 asks for 3; the limits 20.9875 / 21.0125 need 4 and keep them.
  EXPECT_EQ(declaredDecimals(0.05, 21.0 - 0.0125, 21.0 + 0.0125), 4);
  EXPECT_EQ(declaredDecimals(0.05, 21.0 - 0.05, 21.0 + 0.05), 3);
}

// Refused with the key, the value and AQDEF's limit; nothing returned.
std::string refusal(const LotExportContext& context, const std::vector<StoredPart>& parts) {
  try {
    const std::string text = lotDfq(context, parts);
    ADD_FAILURE() << "not refused; wrote:\n" << text.substr(0, 200);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Export, DfqRefusesFieldsLongerThanAqdefAllows) {
  const auto parts = lot();
  // 14 characters: K0006's length, written whole.
  const test::DfqFile ok = test::readDfq(lotDfq({"LOT-2026-12-04", "prism_jaw", ""}, parts));
  expectOnlyAqdefFields(ok);
  EXPECT_EQ(ok.characteristics.at(1).values.at(0).fields.at(6), "LOT-2026-12-04");

  const std::string lot15 = refusal({"LOT-2026-12-04A", "prism_jaw", ""}, parts);
  EXPECT_NE(lot15.find("K0006"), std::string::npos) << lot15;
  EXPECT_NE(lot15.find("'LOT-2026-12-04A'"), std::string::npos) << lot15;
  EXPECT_NE(lot15.find("15 characters"), std::string::npos) << lot15;
  EXPECT_NE(lot15.find("at most 14"), std::string::npos) << lot15;
  // Also when no part was measured (the lot is still the file's batch).
  EXPECT_NE(refusal({"LOT-2026-12-04A", "prism_jaw", ""}, {}).find("K0006"), std::string::npos);

  const std::string k1001 = refusal({"L7", std::string(31, 'n'), ""}, parts);
  EXPECT_NE(k1001.find("K1001"), std::string::npos) << k1001;
  EXPECT_NE(k1001.find("at most 30"), std::string::npos) << k1001;
  EXPECT_NE(refusal({"L7", "", ""}, parts).find("K1001"), std::string::npos);

  const std::string k1002 = refusal({"L7", "prism_jaw", std::string(81, 'd')}, parts);
  EXPECT_NE(k1002.find("K1002"), std::string::npos) << k1002;
  EXPECT_NE(k1002.find("at most 80"), std::string::npos) << k1002;
  // 80 characters, counted as characters (UTF-8 'ä' is two bytes).
  std::string umlauts;
  for (int k = 0; k < 40; ++k) umlauts += std::string("\xC3\xA4") + "a";
  EXPECT_EQ(test::dfqCharacters(umlauts), 80u);
  EXPECT_EQ(test::readDfq(lotDfq({"L7", "prism_jaw", umlauts}, parts)).part.at(1002), umlauts);

  auto long_id = parts;
  long_id[2].part = std::string(41, 'p');
  const std::string k0014 = refusal({"L7", "prism_jaw", ""}, long_id);
  EXPECT_NE(k0014.find("K0014/1"), std::string::npos) << k0014;
  EXPECT_NE(k0014.find("at most 40"), std::string::npos) << k0014;

  auto long_name = parts;
  for (auto& p : long_name)
    for (auto& d : p.dimensions)
      if (d.name == "angle") d.name = std::string(41, 'a');
  const std::string k2001 = refusal({"L7", "prism_jaw", ""}, long_name);
  EXPECT_NE(k2001.find("K2001/2"), std::string::npos) << k2001;

  auto not_a_number = parts;
  not_a_number[4].dimensions[0].value = std::nan("");
  const std::string k0001 = refusal({"L7", "prism_jaw", ""}, not_a_number);
  EXPECT_NE(k0001.find("K0001/1"), std::string::npos) << k0001;
  EXPECT_NE(k0001.find("p0005"), std::string::npos) << k0001;
}

// The reader finds what the writer used to get wrong: it is not a reader
// that passes everything.
TEST(Export, DfqReaderFlagsFieldsAqdefDoesNotDefine) {
  const test::DfqFile bad = test::readDfq(
      "K0100 1\r\n"
      "K1001 part\r\n"
      "K1086 L7\r\n"  // known (work cycle), so no problem: the test above asks it absent
      "K9999 x\r\n"   // not an AQDEF field
      "K2001/1 width\r\n"
      "K2022/1 six\r\n"    // not an integer
      "K2110/1 2.0e1\r\n"  // not a plain decimal
      "K0001/1 20.977\r\n"
      "K0004/1 2026-12-04 06:00:00\r\n"  // not DD.MM.YYYY/HH:MM:SS
      "K0006/1 LOT-2026-12-04A\r\n"      // 15 > 14
      "K0014/2 p1\r\n"                   // before any K0001/2
      "K1002 no CRLF\n");
  const std::string all = ::testing::PrintToString(bad.problems);
  EXPECT_EQ(bad.problems.size(), 7u) << all;
  for (const char* expected :
       {"K9999", "K2022/1", "K2110/1", "K0004/1", "K0006/1", "K0014/2", "CRLF"})
    EXPECT_NE(all.find(expected), std::string::npos) << expected << " in " << all;
  EXPECT_EQ(bad.part.at(1086), "L7");
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
