#include "base/json_writer.h"

#include <spdlog/fmt/fmt.h>

#include <array>
#include <charconv>
#include <cmath>
#include <stdexcept>

namespace felt {

std::string JsonQuote(std::string_view text) {
  std::string out = "\"";
  for (const char c : text) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          out += fmt::format("\\u{:04x}", static_cast<unsigned>(static_cast<unsigned char>(c)));
        } else {
          out += c;
        }
    }
  }
  out += '"';
  return out;
}

void JsonWriter::Indent() { out_.append(static_cast<size_t>(2 * depth_), ' '); }

void JsonWriter::Key(std::string_view key) {
  if (done_ || depth_ == 0) throw std::logic_error("JsonWriter: a member outside any object");
  if (!first_in_object_) out_ += ",";
  out_ += "\n";
  first_in_object_ = false;
  Indent();
  out_ += JsonQuote(key);
  out_ += ": ";
}

void JsonWriter::BeginObject(std::string_view key) {
  if (depth_ == 0) {
    if (done_ || !key.empty()) throw std::logic_error("JsonWriter: one top-level object, no key");
  } else {
    Key(key);
  }
  out_ += "{";
  ++depth_;
  first_in_object_ = true;
}

void JsonWriter::EndObject() {
  if (depth_ == 0) throw std::logic_error("JsonWriter: EndObject() without an open object");
  --depth_;
  if (!first_in_object_) {
    out_ += "\n";
    Indent();
  }
  out_ += "}";
  first_in_object_ = false;
  if (depth_ == 0) {
    out_ += "\n";
    done_ = true;
  }
}

void JsonWriter::Number(std::string_view key, double value) {
  Key(key);
  out_ += std::isfinite(value) ? fmt::format("{}", value) : "null";
}

void JsonWriter::Integer(std::string_view key, int64_t value) {
  Key(key);
  out_ += std::to_string(value);
}

void JsonWriter::Unsigned(std::string_view key, uint64_t value) {
  Key(key);
  out_ += std::to_string(value);
}

void JsonWriter::Bool(std::string_view key, bool value) {
  Key(key);
  out_ += value ? "true" : "false";
}

void JsonWriter::String(std::string_view key, std::string_view value) {
  Key(key);
  out_ += JsonQuote(value);
}

const std::string& JsonWriter::str() const {
  if (!done_) throw std::logic_error("JsonWriter: the document is not closed");
  return out_;
}

std::string ShortestNumberText(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  std::array<char, 64> buffer{};
  const std::to_chars_result result =
      std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  return std::string(buffer.data(), result.ptr);
}

}  // namespace felt
