#include "xgauge/core/config.h"

#include "xgauge/core/did_you_mean.h"

#include "xgauge/core/digest.h"
#include "xgauge/core/file.h"

#include <algorithm>
#include <map>
#include <cmath>
#include <fstream>
#include <iterator>
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
  // Line of every object member and of every object or array, by JSON
  // pointer (parsed text only); a scalar in an array takes its array's.
  std::map<std::string, int> lines;
  // A derived document's place in the file it came from ("/job"): errors
  // name the key as the file has it.
  std::string prefix;

  SourceLocation locate(const std::string& pointer) const {
    const std::string named = prefix + pointer;
    SourceLocation where = SourceLocation::at(origin, named.empty() ? "/" : named);
    for (std::string p = pointer;;) {
      if (const auto it = lines.find(p); it != lines.end()) {
        where.line = it->second;
        break;
      }
      if (p.empty()) break;
      const size_t slash = p.rfind('/');
      p.resize(slash == std::string::npos ? 0 : slash);
    }
    return where;
  }
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

// A short description of a value for "expected X, got Y" messages: scalars
// as written (long strings cut), containers by kind and size, so a message
// never grows with the input.
std::string describeValue(const nlohmann::json& value) {
  constexpr size_t kShown = 40;
  switch (value.type()) {
    case nlohmann::json::value_t::object:
      return fmt::format("an object with {} keys", value.size());
    case nlohmann::json::value_t::array:
      return fmt::format("an array of {} elements", value.size());
    case nlohmann::json::value_t::string: {
      const auto& text = value.get_ref<const std::string&>();
      if (text.size() <= kShown) return value.dump();
      // Cutting may split a UTF-8 sequence: dump() replaces it rather than throwing.
      return nlohmann::json(text.substr(0, kShown))
                 .dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) +
             fmt::format("... ({} bytes)", text.size());
    }
    default:
      return value.dump();
  }
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

namespace {

// Deeper nesting than any configuration needs; the limit keeps a hostile
// file from exhausting the stack of whoever walks or prints the tree.
constexpr size_t kMaxNesting = 128;

// "line L, column C" of byte `offset` of `text`, as a SourceLocation.
SourceLocation locate(std::string_view text, size_t offset, const std::string& origin) {
  SourceLocation where{origin, "", 1, 1};
  const size_t end = std::min(offset, text.size());
  for (size_t i = 0; i < end; ++i) {
    if (text[i] == '\n') {
      ++where.line;
      where.column = 1;
    } else {
      ++where.column;
    }
  }
  return where;
}

// The parser reads the text through this iterator, so the position of the
// last character read is known at every SAX event (nlohmann's SAX interface
// reports positions for syntax errors only).
class TrackedIterator {
 public:
  using iterator_category = std::input_iterator_tag;
  using value_type = char;
  using difference_type = std::ptrdiff_t;
  using pointer = const char*;
  using reference = const char&;

  TrackedIterator(const char* at, const char** cursor) : at_(at), cursor_(cursor) {}
  reference operator*() const { return *at_; }
  TrackedIterator& operator++() {
    *cursor_ = ++at_;
    return *this;
  }
  bool operator==(const TrackedIterator& other) const { return at_ == other.at_; }
  bool operator!=(const TrackedIterator& other) const { return at_ != other.at_; }

 private:
  const char* at_;
  const char** cursor_;
};

// Builds the document from nlohmann's SAX events, refusing what its DOM
// parser would accept silently: nesting deeper than kMaxNesting and a key
// given twice in one object (the DOM parser keeps the last). Every refusal,
// and every syntax or number-range error, becomes an Error with the file,
// line and column.
class DocumentBuilder final : public nlohmann::json_sax<nlohmann::json> {
 public:
  DocumentBuilder(std::string_view text, const std::string& origin, const char** cursor,
                  std::map<std::string, int>& lines)
      : text_(text), origin_(origin), cursor_(cursor), lines_(lines) {}

  nlohmann::json& root() { return root_; }
  // The refusal that stopped the parse, if any.
  const std::optional<Error>& error() const { return error_; }

  bool null() override { return add(nullptr); }
  bool boolean(bool value) override { return add(value); }
  bool number_integer(number_integer_t value) override { return add(value); }
  bool number_unsigned(number_unsigned_t value) override { return add(value); }
  bool number_float(number_float_t value, const string_t&) override { return add(value); }
  bool string(string_t& value) override { return add(std::move(value)); }
  bool binary(binary_t& value) override { return add(nlohmann::json::binary(std::move(value))); }
  bool start_object(std::size_t) override { return open(nlohmann::json::object()); }
  bool start_array(std::size_t) override { return open(nlohmann::json::array()); }
  bool end_object() override { return close(); }
  bool end_array() override { return close(); }
  bool key(string_t& key) override {
    if (open_.back()->contains(key))
      return refuse(fmt::format("key '{}' appears twice in the object at {}", key,
                                paths_.back().empty() ? "/" : paths_.back()));
    lines_.emplace(paths_.back() + "/" + escapeKey(key), line());
    key_ = std::move(key);
    return true;
  }
  bool parse_error(std::size_t position, const std::string&,
                   const nlohmann::json::exception& e) override {
    std::string what = e.what();
    // Drop nlohmann's "[json.exception.parse_error.101] parse error at line
    // 1, column 2: " prefix: the location is ours.
    for (const char* marker : {"syntax error", "number overflow"}) {
      const auto at = what.find(marker);
      if (at != std::string::npos) {
        what = what.substr(at);
        break;
      }
    }
    error_ = Error("malformed JSON: " + what,
                   locate(text_, position == 0 ? 0 : position - 1, origin_));
    return false;
  }

 private:
  // Where the next value goes: the root, the open array, or the open object
  // under the last key.
  nlohmann::json* place(nlohmann::json&& value) {
    if (open_.empty()) {
      root_ = std::move(value);
      return &root_;
    }
    nlohmann::json& parent = *open_.back();
    if (parent.is_array()) {
      parent.push_back(std::move(value));
      return &parent.back();
    }
    nlohmann::json& slot = parent[key_];
    slot = std::move(value);
    return &slot;
  }
  bool add(nlohmann::json&& value) {
    place(std::move(value));
    return true;
  }
  bool open(nlohmann::json&& container) {
    if (open_.size() >= kMaxNesting)
      return refuse(fmt::format("objects and arrays nested more than {} levels deep", kMaxNesting));
    std::string path;
    if (!open_.empty())
      path = paths_.back() + "/" +
             (open_.back()->is_array() ? std::to_string(open_.back()->size()) : escapeKey(key_));
    open_.push_back(place(std::move(container)));
    lines_.emplace(path, line());
    paths_.push_back(std::move(path));
    return true;
  }
  bool close() {
    open_.pop_back();
    paths_.pop_back();
    return true;
  }
  // The line of the parser's position; the cursor only moves forward, so
  // the newlines are counted once.
  int line() {
    const size_t offset = static_cast<size_t>(*cursor_ - text_.data());
    for (; counted_ < offset && counted_ < text_.size(); ++counted_)
      if (text_[counted_] == '\n') ++line_;
    return line_;
  }
  bool refuse(const std::string& message) {
    const size_t offset = static_cast<size_t>(*cursor_ - text_.data());
    error_ = Error(message, locate(text_, offset == 0 ? 0 : offset - 1, origin_));
    return false;
  }

  std::string_view text_;
  const std::string& origin_;
  const char** cursor_;
  nlohmann::json root_;
  std::vector<nlohmann::json*> open_;
  std::map<std::string, int>& lines_;
  size_t counted_ = 0;  // text_[0, counted_) scanned for newlines
  int line_ = 1;
  std::vector<std::string> paths_;  // JSON pointer of each open container
  std::string key_;
  std::optional<Error> error_;
};

}  // namespace

ConfigNode ConfigNode::parse(std::string_view text, const std::string& origin) {
  const char* cursor = text.data();
  std::map<std::string, int> lines;
  DocumentBuilder builder(text, origin, &cursor, lines);
  const bool parsed = nlohmann::json::sax_parse(
      TrackedIterator(text.data(), &cursor), TrackedIterator(text.data() + text.size(), &cursor),
      &builder, nlohmann::json::input_format_t::json, /*strict=*/true, /*ignore_comments=*/true);
  if (!parsed) {
    if (builder.error()) throw *builder.error();
    throw Error("malformed JSON", SourceLocation::inFile(origin));
  }
  ConfigNode node = fromJson(std::move(builder.root()), origin);
  node.doc_->lines = std::move(lines);
  return node;
}

ConfigNode ConfigNode::loadFile(const std::filesystem::path& path) {
  // 256 MiB: far beyond any configuration, raw meshes included.
  const std::string text = readFileContents(path, uint64_t{256} << 20, "a JSON file");
  ConfigNode node = parse(text, path.string());
  node.doc_->sha256 = sha256Hex(text);
  return node;
}

const std::string& ConfigNode::file() const { return doc_->origin; }

const std::string& ConfigNode::sha256() const { return doc_->sha256; }

SourceLocation ConfigNode::where() const {
  return doc_->locate(path_);
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
  if (node) return *node;
  // An unknown key is named before the missing one it misspells: a
  // "detektor" beside no "detector" is the user's typo, not an omission.
  const auto& asked = doc_->asked[path_];
  for (const auto& item : json_->items())
    if (const size_t d = editDistance(item.key(), key);
        !asked.count(item.key()) && d <= 2 && 3 * d < key.size())
      throw Error(fmt::format("unknown key '{}'; did you mean '{}'?", item.key(), key),
                  doc_->locate(path_ + "/" + escapeKey(item.key())));
  fail(fmt::format("missing key '{}'", key));
}

ConfigNode ConfigNode::derived(nlohmann::json document) const {
  auto doc = std::make_shared<Document>();
  doc->root = std::move(document);
  doc->origin = doc_->origin;
  doc->prefix = doc_->prefix + path_;
  // This node's lines, re-based: the derived document's "/a/b" is this
  // node's "<path>/a/b" in the file.
  for (auto it = doc_->lines.lower_bound(path_); it != doc_->lines.end(); ++it) {
    if (!it->first.starts_with(path_)) break;
    const std::string rest = it->first.substr(path_.size());
    if (rest.empty() || rest.front() == '/') doc->lines.emplace(rest, it->second);
  }
  return ConfigNode(doc, &doc->root, "");
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
  if (!json_->is_number()) fail(fmt::format("expected a number, got {}", describeValue(*json_)));
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

int64_t ConfigNode::integer(int64_t min, int64_t max) const {
  const double value = number();
  if (value != std::floor(value)) fail(fmt::format("expected a whole number, got {}", value));
  if (value < static_cast<double>(min) || value > static_cast<double>(max))
    fail(fmt::format("value {} out of range [{}, {}]", value, min, max));
  return static_cast<int64_t>(value);
}

std::string ConfigNode::string() const {
  if (!json_->is_string()) fail(fmt::format("expected a string, got {}", describeValue(*json_)));
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
      const std::string hint =
          didYouMean(item.key(), std::vector<std::string_view>(known.begin(), known.end()));
      throw Error(fmt::format("unknown key '{}'{}", item.key(), hint),
                  doc_->locate(child));
    }
  } else if (json_->is_array()) {
    for (size_t i = 0; i < json_->size(); ++i) {
      const std::string child = path_ + "/" + std::to_string(i);
      if (doc_->read.count(child)) ConfigNode(doc_, &(*json_)[i], child).finish();
    }
  }
}

}  // namespace xgauge
