#include "xgauge/production/export.h"

#include "xgauge/core/error.h"

#include <fmt/format.h>

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

struct Characteristic {
  std::string name, unit;
  std::optional<double> nominal, lsl, usl;
};

// The characteristics in the order the parts list them, with the latest
// tolerance seen.
std::vector<Characteristic> characteristics(const std::vector<StoredPart>& parts) {
  std::vector<Characteristic> out;
  std::map<std::string, size_t> at;
  for (const auto& p : parts)
    for (const auto& d : p.dimensions) {
      if (!at.count(d.name)) at[d.name] = out.size(), out.push_back({d.name, d.unit, {}, {}, {}});
      Characteristic& c = out[at[d.name]];
      if (d.lower_limit) c.nominal = d.nominal, c.lsl = d.lower_limit, c.usl = d.upper_limit;
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
  const auto field = [&](const std::string& key, const std::string& value) {
    out += key + " " + oneLine(value) + "\r\n";
  };
  field("K0100", std::to_string(chars.size()));
  field("K1001", context.part_number);
  field("K1002", context.part_description);
  field("K1086", context.lot);
  for (size_t i = 0; i < chars.size(); ++i) {
    const std::string n = fmt::format("/{}", i + 1);
    const auto& c = chars[i];
    field("K2001" + n, c.name);
    field("K2002" + n, c.name + " (" + c.unit + ")");
    field("K2022" + n, "6");
    if (c.nominal) field("K2101" + n, number(*c.nominal));
    if (c.lsl) field("K2110" + n, number(*c.lsl));
    if (c.usl) field("K2111" + n, number(*c.usl));
    field("K2142" + n, c.unit);
  }
  for (const auto& p : parts) {
    if (p.status != "measured") continue;
    const std::string time = aqdefTime(p.acquired_at);
    for (size_t i = 0; i < chars.size(); ++i) {
      const std::string n = fmt::format("/{}", i + 1);
      for (const auto& d : p.dimensions) {
        if (d.name != chars[i].name) continue;
        field("K0001" + n, number(d.value));
        field("K0004" + n, time);
        field("K0006" + n, context.lot);
        field("K0014" + n, p.part);
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
