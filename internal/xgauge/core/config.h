// Reading JSON configuration files (part models, machines, materials, jobs).
//
// File -> nlohmann::json tree -> ConfigNode views -> objects. A ConfigNode
// remembers which keys were read; Config::finish() then reports every key
// nobody read, so a misspelled key never passes silently ("unknown key
// 'widht'; did you mean 'width'?"). Every error names the file and the JSON
// pointer of the offending value; parse errors also give line and column.
#pragma once

#include "xgauge/core/error.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace xgauge {

class ConfigNode {
 public:
  // Parses a file; a syntax error throws Error with the file, line and column.
  static ConfigNode loadFile(const std::filesystem::path& path);
  // Parses text (for tests and inline JSON); `origin` names it in errors.
  static ConfigNode parse(std::string_view text, const std::string& origin);
  // Wraps an already parsed document.
  static ConfigNode fromJson(nlohmann::json document, const std::string& origin);
  // A document made from this node's JSON (changed by the caller: paths made
  // absolute, say) whose errors keep this node's file and lines: its "/a/b"
  // is located at this node's "<path>/a/b".
  ConfigNode derived(nlohmann::json document) const;

  bool isObject() const { return json_->is_object(); }
  bool isArray() const { return json_->is_array(); }
  bool isString() const { return json_->is_string(); }
  bool isNumber() const { return json_->is_number(); }

  // Object access. at() requires the key; find() returns nullopt when absent.
  // Both mark the key as read.
  bool has(std::string_view key) const;
  ConfigNode at(std::string_view key) const;
  std::optional<ConfigNode> find(std::string_view key) const;
  // Keys in document order... nlohmann sorts them; this is sorted order.
  std::vector<std::string> keys() const;

  // Array access.
  size_t size() const;
  ConfigNode operator[](size_t index) const;

  // Conversions; a wrong type throws naming the key path.
  template <typename T>
  T as() const;
  double number() const;                           // finite double
  double number(double min, double max) const;     // finite, in [min, max]
  // A whole number in [min, max] (2020 and 2020.0 alike; 2.5 is refused).
  int64_t integer(int64_t min, int64_t max) const;
  std::string string() const;

  // Convenience for members of an object.
  template <typename T>
  T get(std::string_view key) const { return at(key).as<T>(); }
  template <typename T>
  T get(std::string_view key, const T& fallback) const {
    auto node = find(key);
    return node ? node->as<T>() : fallback;
  }

  // The raw JSON value (marks the whole subtree as read).
  const nlohmann::json& json() const;

  // Throws an Error located at this node.
  [[noreturn]] void fail(const std::string& message) const;
  SourceLocation where() const;
  const std::string& file() const;
  // SHA-256 of the bytes loadFile() parsed (core/digest.h); empty for parse()
  // and fromJson().
  const std::string& sha256() const;
  const std::string& path() const { return path_; }

  // Throws on the first key under this node that nobody read (checks every
  // object that was looked into, recursively).
  void finish() const;

 private:
  struct Document;
  ConfigNode(std::shared_ptr<Document> doc, const nlohmann::json* json, std::string path);
  void markEntered() const;

  std::shared_ptr<Document> doc_;
  const nlohmann::json* json_;
  std::string path_;  // JSON pointer, "" for the root
};

template <typename T>
T ConfigNode::as() const {
  if constexpr (std::is_same_v<T, double> || std::is_same_v<T, float>) {
    return static_cast<T>(number());
  } else if constexpr (std::is_same_v<T, std::string>) {
    return string();
  } else {
    json();  // mark read
    try {
      return json_->get<T>();
    } catch (const nlohmann::json::exception& e) {
      fail(std::string("wrong type: ") + e.what());
    }
  }
}

}  // namespace xgauge
