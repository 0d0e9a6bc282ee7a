#include "base/json.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace felt {
namespace {

TEST(JsonTest, TextEscapesKeepsOrderAndWritesNonFiniteAsNull) {
  const Json json{{"z", 1},
                  {"a\"b", "line\nnext\\\x01"},
                  {"nan", std::nan("")},
                  {"inf", std::numeric_limits<double>::infinity()},
                  {"neg", -3},
                  {"half", 0.5},
                  {"empty", Json::object()}};
  EXPECT_EQ(JsonText(json),
            "{\n  \"z\": 1,\n  \"a\\\"b\": \"line\\nnext\\\\\\u0001\",\n  \"nan\": null,\n"
            "  \"inf\": null,\n  \"neg\": -3,\n  \"half\": 0.5,\n  \"empty\": {}\n}\n");
}

TEST(JsonTest, ParseReadsWhatTextWrites) {
  const Json json{{"p99", 12.25}, {"ok", true}, {"name", "x"}};
  EXPECT_EQ(ParseJson(JsonText(json), "test"), json);
  EXPECT_THROW(ParseJson("{\"a\": ", "broken.json"), std::runtime_error);
}

TEST(JsonTest, RoundedJsonKeepsTheReportedDecimals) {
  EXPECT_EQ(RoundedJson(1.23456, 3).dump(), "1.235");
  EXPECT_EQ(RoundedJson(2.0, 6).dump(), "2.0");
  EXPECT_TRUE(RoundedJson(std::nan(""), 3).is_null());
}

}  // namespace
}  // namespace felt
