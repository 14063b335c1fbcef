// libFuzzer target: xgauge::ConfigNode (internal/xgauge/core/config.h):
// parse arbitrary text, walk the document with the accessors the loaders use
// (keys, at, find, size, operator[], number, string, json), then finish().
// Expected outcomes: values, or xgauge::Error. Anything else (an nlohmann
// exception escaping, a sanitizer report, stack exhaustion) is a finding.
#include "fuzz_common.h"

#include "xgauge/core/config.h"
#include "xgauge/core/error.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace {

constexpr int kMaxDepth = 12;
constexpr size_t kMaxChildren = 16;

// Reads every value down to kMaxDepth; each accessor may throw Error, which
// is caught per value so the walk goes on.
void walk(const xgauge::ConfigNode& node, int depth, unsigned& choice) {
  ++choice;
  try {
    if (node.isObject()) {
      if (depth >= kMaxDepth) {
        node.json();  // the whole subtree counts as read
        return;
      }
      const auto keys = node.keys();
      for (size_t i = 0; i < keys.size() && i < kMaxChildren; ++i) {
        if (choice % 7 == 0) continue;  // leave some keys unread for finish()
        walk(node.at(keys[i]), depth + 1, choice);
      }
      (void)node.find("no such key");
      if (choice % 5 == 0) (void)node.at("missing");  // throws
    } else if (node.isArray()) {
      const size_t n = node.size();
      for (size_t i = 0; i < n && i < kMaxChildren; ++i) walk(node[i], depth + 1, choice);
      if (choice % 3 == 0) (void)node[n];  // out of range: throws
    } else if (node.isNumber()) {
      (void)node.number();
      (void)node.as<float>();
      (void)node.number(-1e3, 1e3);
    } else if (node.isString()) {
      const std::string text = node.string();
      if (choice % 2 == 0) (void)node.number();  // wrong type: throws
    } else {
      (void)node.where();
      (void)node.number();  // null or bool: throws
    }
  } catch (const xgauge::Error& e) {
    (void)e.where().str();
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  xgauge_fuzz::quietLogging();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const xgauge::ConfigNode root = xgauge::ConfigNode::parse(text, "fuzz.json");
    unsigned choice = size > 0 ? data[0] : 0;
    walk(root, 0, choice);
    root.finish();
  } catch (const xgauge::Error& e) {
    (void)e.where().str();
  }
  return 0;
}
