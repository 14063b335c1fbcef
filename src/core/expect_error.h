// For tests: the call must throw xgauge::Error whose message contains `text`.
#pragma once

#include "xgauge/core/error.h"

#include <gtest/gtest.h>

#include <functional>
#include <string>

namespace xgauge {

inline void expectErrorMentioning(const std::function<void()>& f, const std::string& text) {
  try {
    f();
    ADD_FAILURE() << "no Error thrown; expected one mentioning '" << text << "'";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
  }
}

}  // namespace xgauge
