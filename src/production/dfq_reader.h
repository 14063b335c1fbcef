// A reader of AQDEF (.dfq) K-field files for the tests, written from the
// format's public field list, not from export.cpp (it shares no table or
// function with the writer): each line is "Kxxxx[/i] value" ended by CRLF;
// K00xx are value fields, K0100 the number of characteristics, K1xxx part
// fields, K2xxx characteristic fields (/i: characteristic i). A K0001/i
// line starts a new value of characteristic i and the K00xx/i lines after
// it add to that value.
//
// The fields it knows, their types and maximum lengths, are those of the
// public list: Hexagon PC-DMIS "Q-DAS Configurator: Supported K-Fields"
// (docs.hexagonmi.com/pcdmis/2022.1/en/helpcenter/mergedprojects/
// qdasconfigurator/Supported_K-Fields.htm) for K0xxx and K1xxx, Q-DAS's
// "Characteristic fields K2xxx" (qa.nexus.hexagon.com/community/public/
// q-das/w/data-format/12386) for K2xxx, and "Defined contents K00xx"
// (.../data-format/12488) for K0004's DD.MM.YYYY/HH:MM:SS. Every line that
// is not a known field, is longer than the list allows, or does not parse
// as its type is a problem the reader lists (problems), so a test can ask
// that the writer wrote only fields AQDEF defines, as AQDEF defines them.
#pragma once

#include <cctype>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace xgauge::test {

// 'F' a decimal number (a point, no exponent), 'I' an integer, 'D'
// DD.MM.YYYY/HH:MM:SS, 'A' text. max_length 0: the list gives none.
struct AqdefKey {
  const char* name;
  char type;
  size_t max_length;
};

inline const std::map<int, AqdefKey>& aqdefKeys() {
  static const std::map<int, AqdefKey> keys = {
      // Value level (K00xx).
      {1, {"measured value", 'F', 22}},
      {2, {"attribute", 'I', 5}},
      {4, {"date/time", 'D', 0}},
      {6, {"batch number", 'A', 14}},
      {7, {"cavity number", 'I', 10}},
      {8, {"operator", 'I', 10}},
      {9, {"text", 'A', 255}},
      {10, {"machine number", 'I', 10}},
      {12, {"gage number", 'I', 10}},
      {14, {"part ID", 'A', 40}},
      {15, {"reason for test", 'I', 5}},
      {16, {"production number", 'A', 30}},
      {17, {"workpiece fixture number", 'A', 30}},
      {53, {"order", 'A', 20}},
      {80, {"subgroup ID", 'A', 64}},
      {81, {"value position in subgroup", 'I', 5}},
      // File.
      {100, {"number of characteristics", 'I', 5}},
      // Part level (K1xxx).
      {1001, {"part number", 'A', 30}},
      {1002, {"part description", 'A', 80}},
      {1003, {"part abbreviation", 'A', 20}},
      {1004, {"part amendment status", 'A', 20}},
      {1005, {"product", 'A', 40}},
      {1041, {"drawing number", 'A', 30}},
      {1053, {"contract", 'A', 40}},
      {1081, {"machine number", 'A', 24}},
      {1082, {"machine description", 'A', 40}},
      {1086, {"work cycle / operation number", 'A', 40}},
      {1087, {"production cycle description", 'A', 40}},
      {1110, {"order number", 'A', 20}},
      // Characteristic level (K2xxx).
      {2001, {"characteristic number", 'A', 40}},
      {2002, {"characteristic description", 'A', 80}},
      {2003, {"characteristic abbreviation", 'A', 80}},
      {2004, {"characteristic type", 'I', 0}},
      {2022, {"decimal places", 'I', 0}},
      {2101, {"nominal value", 'F', 0}},
      {2110, {"lower specification limit", 'F', 0}},
      {2111, {"upper specification limit", 'F', 0}},
      {2142, {"unit", 'A', 0}},
  };
  return keys;
}

struct DfqValue {
  std::map<int, std::string> fields;  // K00xx number -> text (1: value, 4: time, 6: batch, ...)
};

struct DfqCharacteristic {
  std::map<int, std::string> fields;  // K2xxx number -> text
  std::vector<DfqValue> values;
};

struct DfqFile {
  std::map<int, std::string> part;                   // K1xxx
  std::map<int, std::string> other;                  // K0100
  std::map<int, DfqCharacteristic> characteristics;  // by i
  std::set<int> keys;                                // every K number read
  std::vector<std::string> problems;                 // empty: every line as AQDEF defines it
  size_t lines = 0;
};

// Characters of UTF-8 text (continuation bytes do not count).
inline size_t dfqCharacters(const std::string& text) {
  size_t n = 0;
  for (unsigned char c : text) n += (c & 0xC0) != 0x80;
  return n;
}

// Digits after the decimal point of a number's text (0 without one).
inline int dfqDecimals(const std::string& number) {
  const size_t point = number.find('.');
  return point == std::string::npos ? 0 : static_cast<int>(number.size() - point - 1);
}

namespace dfq_detail {

inline bool digits(const std::string& s, size_t from, size_t count) {
  if (from + count > s.size()) return false;
  for (size_t k = from; k < from + count; ++k)
    if (!std::isdigit(static_cast<unsigned char>(s[k]))) return false;
  return true;
}

inline bool isInteger(const std::string& s) {
  const size_t start = !s.empty() && s[0] == '-' ? 1 : 0;
  return s.size() > start && digits(s, start, s.size() - start);
}

inline bool isDecimal(const std::string& s) {
  const size_t point = s.find('.');
  if (point == std::string::npos) return isInteger(s);
  return isInteger(s.substr(0, point)) && point + 1 < s.size() &&
         digits(s, point + 1, s.size() - point - 1);
}

inline bool isDateTime(const std::string& s) {
  if (s.size() != 19 || s[2] != '.' || s[5] != '.' || s[10] != '/' || s[13] != ':' || s[16] != ':')
    return false;
  for (size_t k : {0u, 3u, 6u, 11u, 14u, 17u})
    if (!digits(s, k, k == 6 ? 4 : 2)) return false;
  const int day = std::stoi(s.substr(0, 2)), month = std::stoi(s.substr(3, 2));
  const int hour = std::stoi(s.substr(11, 2)), minute = std::stoi(s.substr(14, 2));
  const int second = std::stoi(s.substr(17, 2));
  return day >= 1 && day <= 31 && month >= 1 && month <= 12 && hour <= 23 && minute <= 59 &&
         second <= 59;
}

}  // namespace dfq_detail

inline DfqFile readDfq(const std::string& text) {
  using namespace dfq_detail;
  DfqFile file;
  const auto problem = [&](size_t line, const std::string& what) {
    file.problems.push_back("line " + std::to_string(line) + ": " + what);
  };
  size_t begin = 0;
  while (begin < text.size()) {
    const size_t end = text.find('\n', begin);
    std::string line = text.substr(begin, end == std::string::npos ? end : end - begin);
    begin = end == std::string::npos ? text.size() : end + 1;
    const size_t at = ++file.lines;
    if (line.empty() || line.back() != '\r' || end == std::string::npos) {
      problem(at, "not ended by CRLF");
    } else {
      line.pop_back();
    }
    // "Kxxxx", optionally "/i", one space, the value.
    if (line.size() < 5 || line[0] != 'K' || !digits(line, 1, 4)) {
      problem(at, "not a K-field line: '" + line + "'");
      continue;
    }
    const int number = std::stoi(line.substr(1, 4));
    size_t next = 5;
    int index = 0;
    if (next < line.size() && line[next] == '/') {
      size_t stop = next + 1;
      while (stop < line.size() && std::isdigit(static_cast<unsigned char>(line[stop]))) ++stop;
      if (stop == next + 1) {
        problem(at, "no characteristic number after '/'");
        continue;
      }
      index = std::stoi(line.substr(next + 1, stop - next - 1));
      next = stop;
    }
    if (next >= line.size() || line[next] != ' ') {
      problem(at, "no space between the key and the value");
      continue;
    }
    const std::string value = line.substr(next + 1);
    const std::string key = line.substr(0, next);
    file.keys.insert(number);
    const auto known = aqdefKeys().find(number);
    if (known == aqdefKeys().end()) {
      problem(at, key + " is not a field of the AQDEF list");
      continue;
    }
    const AqdefKey& field = known->second;
    if (field.max_length && dfqCharacters(value) > field.max_length)
      problem(at, key + " (" + field.name + "): '" + value + "' has " +
                      std::to_string(dfqCharacters(value)) + " characters, more than " +
                      std::to_string(field.max_length));
    const bool typed = field.type == 'F'   ? isDecimal(value)
                       : field.type == 'I' ? isInteger(value)
                       : field.type == 'D' ? isDateTime(value)
                                           : true;
    if (!typed)
      problem(at, key + " (" + field.name + "): '" + value + "' is not of type " +
                      std::string(1, field.type));
    if (number >= 1000 && number < 2000) {
      if (index != 0) problem(at, key + ": a part field of a one-part file has no /i");
      if (!file.part.emplace(number, value).second) problem(at, key + " given twice");
    } else if (number >= 2000 && number < 3000) {
      if (index < 1) problem(at, key + ": a characteristic field needs /i, i >= 1");
      if (!file.characteristics[index].fields.emplace(number, value).second)
        problem(at, key + " given twice");
    } else if (number < 100) {
      if (index < 1) {
        problem(at, key + ": a value field needs /i, i >= 1");
        continue;
      }
      const auto described = file.characteristics.find(index);
      if (number != 1 &&
          (described == file.characteristics.end() || described->second.values.empty())) {
        problem(at, key + " before any K0001/" + std::to_string(index));
        continue;
      }
      auto& values = file.characteristics[index].values;
      if (number == 1) values.emplace_back();
      if (!values.back().fields.emplace(number, value).second)
        problem(at, key + " given twice for one value");
    } else {
      if (index != 0) problem(at, key + ": a file field has no /i");
      file.other[number] = value;
    }
  }
  // K0100 counts the characteristics, numbered 1..K0100, each with K2001 or K2002.
  const auto count = file.other.find(100);
  if (count == file.other.end()) {
    file.problems.push_back("no K0100");
  } else if (isInteger(count->second)) {
    const size_t n = static_cast<size_t>(std::stoul(count->second));
    if (file.characteristics.size() != n)
      file.problems.push_back("K0100 is " + count->second + " but " +
                              std::to_string(file.characteristics.size()) +
                              " characteristics are described");
    for (const auto& [i, c] : file.characteristics)
      if (i < 1 || static_cast<size_t>(i) > n || (!c.fields.count(2001) && !c.fields.count(2002)))
        file.problems.push_back("characteristic " + std::to_string(i) +
                                " is outside 1..K0100 or has neither K2001 nor K2002");
  }
  return file;
}

}  // namespace xgauge::test
