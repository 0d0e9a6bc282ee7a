#pragma once
// A small JSON emitter for statistics and benchmark files: nested objects of numbers, booleans
// and strings, written in order, two-space indented. Not for the real-time tick (it allocates).

#include <cstdint>
#include <string>
#include <string_view>

namespace felt {

/// Builds one JSON document of nested objects. Start with BeginObject() (no key), end with a
/// matching EndObject(); inside an object every call takes the member's key. Keys and strings
/// are escaped; non-finite numbers are written as null. Misuse (a key at the top level, an
/// EndObject() too many, str() before the document is closed) throws std::logic_error.
class JsonWriter {
 public:
  /// Opens the top-level object (`key` empty) or a member object named `key`.
  void BeginObject(std::string_view key = {});
  /// Closes the innermost open object.
  void EndObject();
  /// Writes a floating-point member (shortest round-trip form; null when not finite).
  void Number(std::string_view key, double value);
  /// Writes a signed integer member.
  void Integer(std::string_view key, int64_t value);
  /// Writes an unsigned integer member.
  void Unsigned(std::string_view key, uint64_t value);
  /// Writes a boolean member.
  void Bool(std::string_view key, bool value);
  /// Writes a string member.
  void String(std::string_view key, std::string_view value);

  /// The finished document, with a final newline.
  const std::string& str() const;

 private:
  void Key(std::string_view key);
  void Indent();

  std::string out_;
  int depth_ = 0;
  bool first_in_object_ = true;
  bool done_ = false;
};

/// `text` as a JSON string literal, quotes included.
std::string JsonQuote(std::string_view text);

/// `value` in shortest round-trip form (std::to_chars): "0.5", "1e-05", "nan", "inf", "-inf".
std::string ShortestNumberText(double value);

}  // namespace felt
