#pragma once
// JSON for statistics, reports and benchmark files: nlohmann's ordered_json (Debian's
// nlohmann-json3-dev), so members keep the order they are added in. Not for the real-time tick or
// the sim frame (everything here allocates).

#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

namespace felt {

/// A JSON value whose object members keep their insertion order.
using Json = nlohmann::ordered_json;

/// `json` as the project writes documents: two-space indented, a final newline, non-finite numbers
/// as null, doubles in shortest round-trip form.
std::string JsonText(const Json& json);

/// `value` [any unit] rounded to `decimals` decimals, the precision a report prints it with;
/// null when not finite.
Json RoundedJson(double value, int decimals);

/// Parses `text`; throws std::runtime_error naming `what` (e.g. a file name) when it is not JSON.
Json ParseJson(std::string_view text, std::string_view what);

}  // namespace felt
