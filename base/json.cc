#include "base/json.h"

#include <cmath>
#include <stdexcept>

namespace felt {

std::string JsonText(const Json& json) { return json.dump(2) + "\n"; }

Json RoundedJson(double value, int decimals) {
  if (!std::isfinite(value)) return nullptr;
  const double scale = std::pow(10.0, decimals);
  return std::round(value * scale) / scale;
}

Json ParseJson(std::string_view text, std::string_view what) {
  try {
    return Json::parse(text);
  } catch (const Json::parse_error& error) {
    throw std::runtime_error(std::string(what) + ": not JSON: " + error.what());
  }
}

}  // namespace felt
