// A reader of AQDEF (.dfq) K-field files for the tests, written from the
// format's public description (Q-DAS ASCII transfer format), not from
// export.cpp: each line is "Kxxxx[/i] value"; K2xxx/i describe
// characteristic i; a K0001/i line starts a new value of characteristic i
// and the K00xx/i lines after it add to that value.
#pragma once

#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace xgauge::test {

struct DfqValue {
  std::map<int, std::string> fields;  // K00xx number -> text (1: value, 4: time, ...)
};

struct DfqCharacteristic {
  std::map<int, std::string> fields;  // K2xxx number -> text
  std::vector<DfqValue> values;
};

struct DfqFile {
  std::map<int, std::string> part;                   // K1xxx
  std::map<int, std::string> other;                  // K0100, ...
  std::map<int, DfqCharacteristic> characteristics;  // by i
};

inline DfqFile readDfq(const std::string& text) {
  DfqFile file;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.size() < 5 || line[0] != 'K') continue;
    const size_t space = line.find(' ');
    const std::string key =
        line.substr(1, space == std::string::npos ? std::string::npos : space - 1);
    const std::string value = space == std::string::npos ? "" : line.substr(space + 1);
    const size_t slash = key.find('/');
    const int number = std::stoi(key.substr(0, slash));
    const int index = slash == std::string::npos ? 0 : std::stoi(key.substr(slash + 1));
    if (number >= 1000 && number < 2000) {
      file.part[number] = value;
    } else if (number >= 2000 && number < 3000) {
      file.characteristics[index].fields[number] = value;
    } else if (number < 100 && index > 0) {
      auto& values = file.characteristics[index].values;
      if (number == 1 || values.empty()) values.emplace_back();
      values.back().fields[number] = value;
    } else {
      file.other[number] = value;
    }
  }
  return file;
}

}  // namespace xgauge::test
