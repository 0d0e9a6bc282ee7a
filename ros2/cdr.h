#pragma once
// Classic CDR, little-endian, as ROS 2 puts it on the wire (XCDR1, the OMG DDS-XTypes 1.3 §7.4.3
// "PLAIN_CDR" rules; ../shared/notes/ros2-wire.md): a 4-byte encapsulation header 00 01 00 00
// (CDR_LE), then each primitive aligned to its own size (8 for float64/int64) counted from the end
// of that header; a string is a uint32 length that counts its terminating NUL, the bytes and the
// NUL; a sequence is a uint32 element count and the elements. CdrReader checks every read against
// the buffer's end and throws a CdrError naming the type, the field and the byte offset.

#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace felt::ros2 {

/// The encapsulation header of little-endian classic CDR (CDR_LE): representation id 0x0001,
/// options 0x0000.
inline constexpr uint8_t kCdrLeHeader[4] = {0x00, 0x01, 0x00, 0x00};

/// Truncated or malformed CDR bytes. what() reads "TYPE: field FIELD at byte OFFSET: message";
/// the offset counts from the first byte of the buffer (the encapsulation header included).
class CdrError : public std::runtime_error {
 public:
  CdrError(std::string type, std::string field, size_t offset, const std::string& message);
  const std::string& type() const { return type_; }    ///< e.g. "geometry_msgs/msg/PoseStamped"
  const std::string& field() const { return field_; }  ///< e.g. "header.frame_id"
  size_t offset() const { return offset_; }            ///< byte offset in the buffer

 private:
  std::string type_;
  std::string field_;
  size_t offset_;
};

/// Appends one message in little-endian classic CDR to a byte vector. The constructor clears the
/// vector and writes the encapsulation header; alignment counts from the end of that header.
/// Allocates only when the vector grows (reuse one vector to serialise without allocating).
class CdrWriter {
 public:
  /// Clears `*out` (capacity kept) and writes kCdrLeHeader.
  explicit CdrWriter(std::vector<uint8_t>* out);

  void U8(uint8_t v);    ///< uint8 / byte / char
  void Bool(bool v);     ///< bool: one byte, 0 or 1
  void I32(int32_t v);   ///< int32, 4-aligned
  void U32(uint32_t v);  ///< uint32, 4-aligned
  void F32(float v);     ///< float32, 4-aligned
  void F64(double v);    ///< float64, 8-aligned
  /// A string: uint32 length (bytes + 1), the bytes, a NUL. Throws std::invalid_argument when
  /// `v` holds a NUL (it could not be read back).
  void String(std::string_view v);
  /// A sequence's element count (uint32); the caller writes the elements after it.
  void SequenceLength(size_t n);
  /// Bytes written so far, header included.
  size_t size() const { return out_->size(); }

 private:
  void Align(size_t n);
  void Raw(const void* p, size_t n);
  std::vector<uint8_t>* out_;
};

/// Reads one little-endian classic CDR message with bounds checks on every field.
class CdrReader {
 public:
  /// Checks the encapsulation header (CDR_LE; big-endian and XCDR2 are refused with a CdrError).
  /// `type` names the message in errors. The bytes must outlive the reader.
  CdrReader(std::span<const uint8_t> bytes, std::string_view type);

  uint8_t U8(const char* field);    ///< uint8 / byte
  bool Bool(const char* field);     ///< bool (a byte other than 0 or 1 is an error)
  int32_t I32(const char* field);   ///< int32
  uint32_t U32(const char* field);  ///< uint32
  float F32(const char* field);     ///< float32
  double F64(const char* field);    ///< float64
  /// A string (length must be >= 1, the bytes must end in NUL and hold no other NUL).
  std::string String(const char* field);
  /// A sequence's element count, checked against the bytes left: each element takes at least
  /// `min_element_bytes` (>= 1), so a count that cannot fit is an error before anything is sized.
  uint32_t SequenceLength(const char* field, size_t min_element_bytes);
  /// Skips `n` bytes of a uint8 sequence's payload.
  void SkipBytes(const char* field, size_t n);
  /// Ends the message: more than 3 bytes left (the most the writer's 4-byte padding adds) is an
  /// error naming the offset.
  void Finish();
  /// Current offset from the first byte of the buffer.
  size_t offset() const { return pos_; }

 private:
  [[noreturn]] void Fail(const char* field, size_t at, const std::string& message) const;
  void Need(const char* field, size_t align, size_t n);
  std::span<const uint8_t> bytes_;
  std::string type_;
  size_t pos_ = 4;
};

}  // namespace felt::ros2
