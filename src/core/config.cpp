#include "xgauge/core/config.h"

#include "xgauge/core/digest.h"

#include <algorithm>
#include <map>
#include <cmath>
#include <fstream>
#include <sstream>

namespace xgauge {

struct ConfigNode::Document {
  nlohmann::json root;
  std::string origin;
  std::string sha256;             // of the file's bytes; empty for parsed text
  std::set<std::string> read;     // pointers whose value was looked up
  std::set<std::string> entered;  // pointers of objects whose keys were looked up
  std::set<std::string> whole;    // pointers read as a whole subtree
  std::map<std::string, std::set<std::string>> asked;  // keys looked up per object, present or not
};

namespace {

std::string escapeKey(std::string_view key) {
  std::string out;
  for (char c : key) {
    if (c == '~') out += "~0";
    else if (c == '/') out += "~1";
    else out += c;
  }
  return out;
}

// Levenshtein distance, for "did you mean" hints.
size_t editDistance(std::string_view a, std::string_view b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

}  // namespace

ConfigNode::ConfigNode(std::shared_ptr<Document> doc, const nlohmann::json* json, std::string path)
    : doc_(std::move(doc)), json_(json), path_(std::move(path)) {}

ConfigNode ConfigNode::fromJson(nlohmann::json document, const std::string& origin) {
  auto doc = std::make_shared<Document>();
  doc->root = std::move(document);
  doc->origin = origin;
  return ConfigNode(doc, &doc->root, "");
}

ConfigNode ConfigNode::parse(std::string_view text, const std::string& origin) {
  try {
    return fromJson(nlohmann::json::parse(text.begin(), text.end(), nullptr, true,
                                          /*ignore_comments=*/true),
                    origin);
  } catch (const nlohmann::json::parse_error& e) {
    // Turn the byte offset into a line and column.
    SourceLocation where{origin, "", 1, 1};
    const size_t end = std::min<size_t>(e.byte == 0 ? 0 : e.byte - 1, text.size());
    for (size_t i = 0; i < end; ++i) {
      if (text[i] == '\n') {
        ++where.line;
        where.column = 1;
      } else {
        ++where.column;
      }
    }
    std::string what = e.what();
    const auto colon = what.find("syntax error");
    throw Error("malformed JSON: " + (colon == std::string::npos ? what : what.substr(colon)),
                where);
  }
}

ConfigNode ConfigNode::loadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("cannot open file", SourceLocation::inFile(path.string()));
  std::stringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) throw Error("cannot read file", SourceLocation::inFile(path.string()));
  const std::string text = buffer.str();
  ConfigNode node = parse(text, path.string());
  node.doc_->sha256 = sha256Hex(text);
  return node;
}

const std::string& ConfigNode::file() const { return doc_->origin; }

const std::string& ConfigNode::sha256() const { return doc_->sha256; }

SourceLocation ConfigNode::where() const {
  return SourceLocation::at(doc_->origin, path_.empty() ? "/" : path_);
}

void ConfigNode::fail(const std::string& message) const { throw Error(message, where()); }

void ConfigNode::markEntered() const { doc_->entered.insert(path_); }

bool ConfigNode::has(std::string_view key) const {
  if (!json_->is_object()) fail("expected an object");
  markEntered();
  doc_->asked[path_].emplace(key);
  const bool present = json_->contains(key);
  if (present) doc_->read.insert(path_ + "/" + escapeKey(key));
  return present;
}

std::optional<ConfigNode> ConfigNode::find(std::string_view key) const {
  if (!has(key)) return std::nullopt;
  return ConfigNode(doc_, &json_->find(key).value(), path_ + "/" + escapeKey(key));
}

ConfigNode ConfigNode::at(std::string_view key) const {
  auto node = find(key);
  if (!node) fail(fmt::format("missing key '{}'", key));
  return *node;
}

std::vector<std::string> ConfigNode::keys() const {
  if (!json_->is_object()) fail("expected an object");
  markEntered();
  std::vector<std::string> out;
  for (const auto& item : json_->items()) out.push_back(item.key());
  return out;
}

size_t ConfigNode::size() const {
  if (!json_->is_array()) fail("expected an array");
  return json_->size();
}

ConfigNode ConfigNode::operator[](size_t index) const {
  if (index >= size()) fail(fmt::format("index {} out of range (size {})", index, size()));
  const std::string child = path_ + "/" + std::to_string(index);
  doc_->read.insert(child);
  return ConfigNode(doc_, &(*json_)[index], child);
}

const nlohmann::json& ConfigNode::json() const {
  doc_->whole.insert(path_);
  return *json_;
}

double ConfigNode::number() const {
  if (!json_->is_number()) fail(fmt::format("expected a number, got {}", json_->dump()));
  const double value = json_->get<double>();
  if (!std::isfinite(value)) fail("expected a finite number");
  return value;
}

double ConfigNode::number(double min, double max) const {
  const double value = number();
  if (value < min || value > max)
    fail(fmt::format("value {} out of range [{}, {}]", value, min, max));
  return value;
}

std::string ConfigNode::string() const {
  if (!json_->is_string()) fail(fmt::format("expected a string, got {}", json_->dump()));
  return json_->get<std::string>();
}

void ConfigNode::finish() const {
  if (doc_->whole.count(path_)) return;
  if (json_->is_object()) {
    if (!doc_->entered.count(path_)) return;
    const auto asked = doc_->asked.find(path_);
    const std::set<std::string> known =
        asked == doc_->asked.end() ? std::set<std::string>{} : asked->second;
    for (const auto& item : json_->items()) {
      const std::string child = path_ + "/" + escapeKey(item.key());
      if (doc_->read.count(child)) {
        ConfigNode(doc_, &item.value(), child).finish();
        continue;
      }
      std::string hint;
      size_t best = 3;
      for (const auto& k : known) {
        const size_t d = editDistance(item.key(), k);
        if (d < best) best = d, hint = fmt::format("; did you mean '{}'?", k);
      }
      throw Error(fmt::format("unknown key '{}'{}", item.key(), hint),
                  SourceLocation::at(doc_->origin, child));
    }
  } else if (json_->is_array()) {
    for (size_t i = 0; i < json_->size(); ++i) {
      const std::string child = path_ + "/" + std::to_string(i);
      if (doc_->read.count(child)) ConfigNode(doc_, &(*json_)[i], child).finish();
    }
  }
}

}  // namespace xgauge
