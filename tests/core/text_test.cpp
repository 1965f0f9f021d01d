// Numbers as text: whole-token parsing (signs, overflow and underflow, nan/inf, junk) and the
// shortest round-trip formatting, checked against values written out by hand.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "core/Text.h"

using viscera::formatNumber;
using viscera::parseInteger;
using viscera::parseNumber;

TEST(Text, ParsesWholeTokensOnly) {
  double v = -1;
  EXPECT_TRUE(parseNumber("0.25", v));
  EXPECT_EQ(v, 0.25);
  EXPECT_TRUE(parseNumber("+3e2", v));
  EXPECT_EQ(v, 300);
  EXPECT_TRUE(parseNumber("-.5", v));
  EXPECT_EQ(v, -0.5);
  for (const char* bad : {"", "+", "++1", "+-1", "1.5x", " 1", "1 ", "0x10", "1,5", "e3"}) {
    v = 7;
    EXPECT_FALSE(parseNumber(bad, v)) << bad;
    EXPECT_EQ(v, 7) << "a failed parse leaves the value alone: " << bad;
  }
}

TEST(Text, OutOfRangeIsInfinityOrZeroNotAnError) {
  double v = 0;
  ASSERT_TRUE(parseNumber("1e999", v));
  EXPECT_EQ(v, std::numeric_limits<double>::infinity());
  ASSERT_TRUE(parseNumber("-1e999", v));
  EXPECT_EQ(v, -std::numeric_limits<double>::infinity());
  ASSERT_TRUE(parseNumber("1e-999", v));
  EXPECT_EQ(v, 0.0);
  ASSERT_TRUE(parseNumber("nan", v));
  EXPECT_TRUE(std::isnan(v));
  ASSERT_TRUE(parseNumber("-inf", v));
  EXPECT_EQ(v, -std::numeric_limits<double>::infinity());
}

TEST(Text, Integers) {
  long long n = 0;
  EXPECT_TRUE(parseInteger("+42", n));
  EXPECT_EQ(n, 42);
  EXPECT_TRUE(parseInteger("-9223372036854775808", n));
  EXPECT_EQ(n, std::numeric_limits<long long>::min());
  for (const char* bad : {"", "4.0", "9223372036854775808", "1e3", "12a"}) EXPECT_FALSE(parseInteger(bad, n)) << bad;
}

TEST(Text, FormattingIsShortestAndReadsBackExactly) {
  EXPECT_EQ(formatNumber(0.1), "0.1");
  EXPECT_EQ(formatNumber(1e-7), "1e-07");
  EXPECT_EQ(formatNumber(1.0 / 3.0), "0.3333333333333333");
  EXPECT_EQ(formatNumber(-0.0), "-0");
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> exponent(-300, 300);
  for (int i = 0; i < 2000; ++i) {
    const double x = std::ldexp(std::uniform_real_distribution<double>(-1, 1)(rng), static_cast<int>(exponent(rng)));
    double y = 0;
    ASSERT_TRUE(parseNumber(formatNumber(x), y)) << formatNumber(x);
    ASSERT_EQ(x, y) << formatNumber(x);
  }
}

TEST(Text, PrintableEscapesBinaryAndCutsLongRuns) {
  using viscera::printable;
  EXPECT_EQ(printable("plain: 'mm' and µm, tab\tand\nline"), "plain: 'mm' and µm, tab\tand\nline");
  EXPECT_EQ(printable(std::string("a\x01") + "b\x7F" + "\xFF\xFE" + "c"), "a\\x01b\\x7F\\xFF\\xFEc");
  EXPECT_EQ(printable("\xC3"), "\\xC3");  // a UTF-8 sequence cut short
  const std::string value(100000, 'x');
  const std::string shown = printable("unknown unit '" + value + "' here", 160);
  EXPECT_LT(shown.size(), 260u);
  EXPECT_NE(shown.find("characters left out"), std::string::npos);
  EXPECT_EQ(shown.substr(0, 20), "unknown unit 'xxxxxx");
  EXPECT_EQ(shown.substr(shown.size() - 10), "xxxx' here");
  // Multi-byte characters are never split.
  std::string wide;
  for (int i = 0; i < 300; ++i) wide += "é";
  const std::string cut = printable(wide, 101);
  EXPECT_EQ(printable(cut), cut);
  EXPECT_EQ(cut.find("\\x"), std::string::npos);
}
