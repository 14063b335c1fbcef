// A lot's results for other software: Q-DAS AQDEF (.dfq), which the
// statistics software in factories (qs-STAT, procella) imports, and CSV.
// docs/formats.md, "Exports".
//
// The .dfq is the K-field form of the AQDEF transfer format, one field per
// line ("Kxxxx/i value", i the characteristic; CRLF line ends):
//   K0100            number of characteristics
//   K1001, K1002     part number (the part model's name) and description
//                    (default: the part number and lot)
//   per characteristic i (each free dimension, in the part model's order):
//   K2001/i, K2002/i number (the dimension's name) and description
//   K2022/i          decimal places: the fewest whose last digit is at most
//                    U/10 (the lot's smallest U), raised to what the plan's
//                    nominal and limits need; 6 without a U
//   K2101/i          nominal; K2110/i, K2111/i lower and upper specification
//                    limits (when toleranced); K2142/i unit
//   per measured part, per characteristic: K0001/i the value (with K2022's
//   decimals), K0004/i the part's acquisition time as DD.MM.YYYY/HH:MM:SS
//   (UTC), K0006/i the lot (batch number, at most 14 characters), K0014/i
//   the part id. A K0001/i line starts a new value of characteristic i; the
//   K00xx/i lines after it belong to it. A field longer than AQDEF allows
//   is refused, nothing written.
// Parts "not measured" have no values and are left out.
#pragma once

#include "xgauge/production/store.h"

#include <string>
#include <vector>

namespace xgauge {

struct LotExportContext {
  std::string lot;
  std::string part_number;       // the part model's name
  std::string part_description;  // free text
};

std::string lotDfq(const LotExportContext& context, const std::vector<StoredPart>& parts);
// One row per part and dimension, RFC 4180 quoting, a header row.
std::string lotCsv(const LotExportContext& context, const std::vector<StoredPart>& parts);

// "2026-12-04T06:00:00Z" -> "04.12.2026/06:00:00"; Error on another form.
std::string aqdefTime(const std::string& iso_utc);

}  // namespace xgauge
