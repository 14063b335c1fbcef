#include "xgauge/production/export.h"

#include "xgauge/core/error.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

namespace xgauge {

namespace {

// AQDEF fields hold one line; a value may not carry a line break.
std::string oneLine(std::string text) {
  for (char& c : text)
    if (c == '\r' || c == '\n') c = ' ';
  return text;
}

std::string csvField(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string out = "\"";
  for (char c : text) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::string number(double v) { return fmt::format("{}", v); }  // shortest exact form
std::string number(const std::optional<double>& v) { return v ? number(*v) : ""; }

// The AQDEF K-fields the .dfq writes, with the maximum length the public
// field list gives: Q-DAS ASCII transfer format as listed by Hexagon's
// "Q-DAS Configurator: Supported K-Fields" (docs.hexagonmi.com/pcdmis/
// 2022.1/en/helpcenter/mergedprojects/qdasconfigurator/Supported_K-Fields.htm:
// K0001 F 22 measured value, K0004 date/time, K0006 AN 14 batch number,
// K0014 AN 40 part ID, K0100 number of characteristics, K1001 AN 30 part
// number, K1002 AN 80 part description; K1086 is "work cycle / operation
// number", K1110 "order number") and Q-DAS's "Characteristic fields K2xxx"
// (qa.nexus.hexagon.com/community/public/q-das/w/data-format/12386: K2001
// characteristic number 40, K2002 description 80, K2022 decimal places).
// The lot is a batch: K0006 on every value.
struct FieldLimit {
  const char* key;
  const char* name;
  size_t max_length;
};
constexpr FieldLimit kFieldLimits[] = {
    {"K0001", "measured value", 22},
    {"K0006", "batch number", 14},
    {"K0014", "part ID", 40},
    {"K1001", "part number", 30},
    {"K1002", "part description", 80},
    {"K2001", "characteristic number", 40},
    {"K2002", "characteristic description", 80},
};

// Characters, not bytes: UTF-8 continuation bytes do not count.
size_t characters(const std::string& text) {
  size_t n = 0;
  for (unsigned char c : text) n += (c & 0xC0) != 0x80;
  return n;
}

// Refuses a value longer than AQDEF allows for `key` ("K0006/1": the
// number before the slash decides), naming the key, the value and the limit.
void checkLength(const std::string& key, const std::string& value, const std::string& what) {
  const std::string number = key.substr(0, key.find('/'));
  for (const auto& limit : kFieldLimits) {
    if (number != limit.key || characters(value) <= limit.max_length) continue;
    fail(
        "dfq: {} ({}): {} '{}' has {} characters; AQDEF allows at most {} in {}: nothing "
        "written",
        key, limit.name, what, value, characters(value), limit.max_length, limit.key);
  }
}

// Decimal places (K2022) of a characteristic. The values are rounded to
// them, so they follow the expanded uncertainty U as GUM 7.2.6 states a
// result: U to two significant digits and the value to the same decimal
// place, i.e. the fewest decimals d with 10^-d <= U/10 (U = 0.004 mm: 4).
// Rounding then moves a value by at most 10^-d / 2 <= U/20. The smallest U
// of the lot's parts decides (every part's rounding stays under its U/20).
// The nominal and the limits are never rounded away: d is at least the
// decimals they need once binary noise is set aside (20.080000000000002
// needs 2). Without any U (a dimension measured without one): 6. At most
// kMaxDecimals.
constexpr int kMaxDecimals = 9;
constexpr int kDecimalsWithoutU = 6;

std::string fixed(double v, int decimals) {
  std::string text = fmt::format("{:.{}f}", v, decimals);
  // -0.0000 is 0.0000.
  if (text.front() == '-' && text.find_first_not_of("-0.") == std::string::npos) text.erase(0, 1);
  return text;
}

// The fewest decimals that write `v` up to binary noise (a few ulps).
int decimalsOf(double v) {
  for (int d = 0; d < kMaxDecimals; ++d)
    if (std::abs(std::stod(fixed(v, d)) - v) <= 1e-12 * std::max(1.0, std::abs(v))) return d;
  return kMaxDecimals;
}

int decimalsForU(double u) {
  for (int d = 0; d < kMaxDecimals; ++d)
    if (std::pow(10.0, -d) <= u / 10.0 * (1.0 + 1e-9)) return d;
  return kMaxDecimals;
}

struct Characteristic {
  std::string name, unit;
  std::optional<double> nominal, lsl, usl;
  std::optional<double> smallest_u;
  int decimals = kDecimalsWithoutU;
};

// The characteristics in the order the parts list them, with the latest
// tolerance seen and the smallest U of the parts measured.
std::vector<Characteristic> characteristics(const std::vector<StoredPart>& parts) {
  std::vector<Characteristic> out;
  std::map<std::string, size_t> at;
  for (const auto& p : parts)
    for (const auto& d : p.dimensions) {
      if (!at.count(d.name)) {
        at[d.name] = out.size();
        out.emplace_back();
        out.back().name = d.name, out.back().unit = d.unit;
      }
      Characteristic& c = out[at[d.name]];
      if (d.lower_limit) c.nominal = d.nominal, c.lsl = d.lower_limit, c.usl = d.upper_limit;
      const auto& u = d.expanded_uncertainty;
      if (p.status == "measured" && u && std::isfinite(*u) && *u > 0.0)
        c.smallest_u = c.smallest_u ? std::min(*c.smallest_u, *u) : *u;
    }
  for (auto& c : out) {
    c.decimals = c.smallest_u ? decimalsForU(*c.smallest_u) : kDecimalsWithoutU;
    for (const auto& v : {c.nominal, c.lsl, c.usl})
      if (v) c.decimals = std::max(c.decimals, decimalsOf(*v));
  }
  return out;
}

}  // namespace

std::string aqdefTime(const std::string& iso) {
  // YYYY-MM-DDTHH:MM:SSZ
  if (iso.size() != 20 || iso[4] != '-' || iso[7] != '-' || iso[10] != 'T' || iso[13] != ':' ||
      iso[16] != ':' || iso[19] != 'Z')
    fail("time '{}': expected UTC as YYYY-MM-DDTHH:MM:SSZ", iso);
  return fmt::format("{}.{}.{}/{}", iso.substr(8, 2), iso.substr(5, 2), iso.substr(0, 4),
                     iso.substr(11, 8));
}

std::string lotDfq(const LotExportContext& context, const std::vector<StoredPart>& parts) {
  const auto chars = characteristics(parts);
  std::string out;
  // Every field is checked before it is added; lotDfq returns the whole
  // text or throws, so the caller writes all of it or nothing.
  const auto field = [&](const std::string& key, const std::string& value,
                         const std::string& what) {
    const std::string text = oneLine(value);
    checkLength(key, text, what);
    out += key + " " + text + "\r\n";
  };
  const auto numberField = [&](const std::string& key, double v, int decimals,
                               const std::string& what) {
    if (!std::isfinite(v)) fail("dfq: {}: {} is {}, not a number: nothing written", key, what, v);
    field(key, fixed(v, decimals), what);
  };
  if (context.part_number.empty()) fail("dfq: K1001 (part number) is empty: nothing written");
  // The lot goes into K0006 (batch number) of every value: checked here, so
  // a lot too long is refused even when no part was measured.
  checkLength("K0006", context.lot, "the lot");
  // K1002 by default: what the file holds, within K1002's 80 characters
  // (K1001 <= 30 and the lot <= 14 are checked above and below).
  std::string description = context.part_description;
  if (description.empty())
    description = context.part_number == context.lot
                      ? fmt::format("lot {}: X-ray measurement (xgauge)", context.lot)
                      : fmt::format("{}, lot {}: X-ray measurement (xgauge)", context.part_number,
                                    context.lot);
  field("K0100", std::to_string(chars.size()), "the number of characteristics");
  field("K1001", context.part_number, "the part number");
  field("K1002", description, "the part description");
  for (size_t i = 0; i < chars.size(); ++i) {
    const std::string n = fmt::format("/{}", i + 1);
    const auto& c = chars[i];
    field("K2001" + n, c.name, "the dimension's name");
    field("K2002" + n, c.name + " (" + c.unit + ")", "the dimension's description");
    field("K2022" + n, std::to_string(c.decimals), "the decimal places");
    const std::string of = fmt::format(" of {}", c.name);
    if (c.nominal) numberField("K2101" + n, *c.nominal, c.decimals, "the nominal" + of);
    if (c.lsl) numberField("K2110" + n, *c.lsl, c.decimals, "the lower limit" + of);
    if (c.usl) numberField("K2111" + n, *c.usl, c.decimals, "the upper limit" + of);
    field("K2142" + n, c.unit, "the unit");
  }
  for (const auto& p : parts) {
    if (p.status != "measured") continue;
    const std::string time = aqdefTime(p.acquired_at);
    for (size_t i = 0; i < chars.size(); ++i) {
      const std::string n = fmt::format("/{}", i + 1);
      for (const auto& d : p.dimensions) {
        if (d.name != chars[i].name) continue;
        numberField("K0001" + n, d.value, chars[i].decimals,
                    fmt::format("part {}'s {}", p.part, d.name));
        field("K0004" + n, time, "the acquisition time");
        field("K0006" + n, context.lot, "the lot");
        field("K0014" + n, p.part, "the part id");
      }
    }
  }
  return out;
}

std::string lotCsv(const LotExportContext& context, const std::vector<StoredPart>& parts) {
  std::string out =
      "lot,part,part_index,acquired_at,measured_at,station,status,dimension,value,unit,"
      "expanded_uncertainty,nominal,lower_limit,upper_limit,verdict,identifiable,verified\r\n";
  for (const auto& p : parts) {
    const std::string head =
        fmt::format("{},{},{},{},{},{},{}", csvField(context.lot), csvField(p.part), p.part_index,
                    p.acquired_at, p.measured_at, csvField(p.station), csvField(p.status));
    if (p.dimensions.empty()) out += head + ",,,,,,,,,,\r\n";
    for (const auto& d : p.dimensions)
      out += fmt::format("{},{},{},{},{},{},{},{},{},{},{}\r\n", head, csvField(d.name),
                         number(d.value), csvField(d.unit), number(d.expanded_uncertainty),
                         number(d.nominal), number(d.lower_limit), number(d.upper_limit),
                         csvField(d.verdict), d.identifiable ? 1 : 0, d.verified ? 1 : 0);
  }
  return out;
}

}  // namespace xgauge
