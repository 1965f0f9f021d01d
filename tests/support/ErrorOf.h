// The message of the viscera::Error a piece of code throws, for tests that check error texts.
#pragma once

#include <string>

#include "core/Error.h"

namespace viscera::test_support {

// Runs `f`; returns the message of the viscera::Error it throws, or "" if it throws none.
template <class F>
std::string errorOf(F&& f) {
  try {
    f();
  } catch (const viscera::Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace viscera::test_support
