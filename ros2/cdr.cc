#include "ros2/cdr.h"

#include <bit>
#include <cstring>

namespace felt::ros2 {

static_assert(std::endian::native == std::endian::little,
              "ros2/cdr.cc copies little-endian CDR as the host's bytes");

namespace {
constexpr size_t kCdrOrigin = 4;  // alignment counts from the end of the encapsulation header
}  // namespace

CdrError::CdrError(std::string type, std::string field, size_t offset, const std::string& message)
    : std::runtime_error(type + ": field " + field + " at byte " + std::to_string(offset) + ": " +
                         message),
      type_(std::move(type)),
      field_(std::move(field)),
      offset_(offset) {}

// ---- CdrWriter ----

CdrWriter::CdrWriter(std::vector<uint8_t>* out) : out_(out) {
  out_->resize(4);
  std::memcpy(out_->data(), kCdrLeHeader, 4);
}

void CdrWriter::Align(size_t n) {
  // Pad with zeros to a multiple of n past the header (XTypes 1.3 §7.4.3.2.2).
  const size_t rel = out_->size() - kCdrOrigin;
  const size_t pad = (n - rel % n) % n;
  out_->resize(out_->size() + pad, uint8_t{0});
}

void CdrWriter::Raw(const void* p, size_t n) {
  // resize + memcpy (GCC 12's -Warray-bounds misfires on vector::insert of a few bytes).
  if (n == 0) return;
  const size_t old = out_->size();
  out_->resize(old + n);
  std::memcpy(out_->data() + old, p, n);
}

void CdrWriter::U8(uint8_t v) { out_->push_back(v); }
void CdrWriter::Bool(bool v) { out_->push_back(v ? 1 : 0); }
void CdrWriter::I32(int32_t v) {
  Align(4);
  Raw(&v, 4);
}
void CdrWriter::U32(uint32_t v) {
  Align(4);
  Raw(&v, 4);
}
void CdrWriter::F32(float v) {
  Align(4);
  Raw(&v, 4);
}
void CdrWriter::F64(double v) {
  Align(8);
  Raw(&v, 8);
}

void CdrWriter::String(std::string_view v) {
  if (v.find('\0') != std::string_view::npos) {
    throw std::invalid_argument("CDR string: must not hold a NUL character");
  }
  U32(static_cast<uint32_t>(v.size() + 1));
  Raw(v.data(), v.size());
  out_->push_back(0);
}

void CdrWriter::SequenceLength(size_t n) { U32(static_cast<uint32_t>(n)); }

// ---- CdrReader ----

CdrReader::CdrReader(std::span<const uint8_t> bytes, std::string_view type)
    : bytes_(bytes), type_(type) {
  if (bytes_.size() < 4) {
    Fail(
        "(encapsulation header)", 0,
        "message of " + std::to_string(bytes_.size()) + " bytes is shorter than the 4-byte header");
  }
  // Representation id 0x0001 = CDR_LE; 0x0000 = CDR_BE; 0x0007+ = XCDR2 (XTypes 1.3 §7.6.3.1.2).
  if (bytes_[0] != 0x00 || bytes_[1] != 0x01) {
    Fail("(encapsulation header)", 0,
         "representation id " + std::to_string(bytes_[0]) + "," + std::to_string(bytes_[1]) +
             " is not little-endian classic CDR (00 01)");
  }
}

void CdrReader::Fail(const char* field, size_t at, const std::string& message) const {
  throw CdrError(type_, field, at, message);
}

void CdrReader::Need(const char* field, size_t align, size_t n) {
  const size_t rel = pos_ - kCdrOrigin;
  const size_t pad = (align - rel % align) % align;
  if (pos_ + pad + n > bytes_.size()) {
    Fail(field, pos_,
         "needs " + std::to_string(pad + n) + " bytes, " + std::to_string(bytes_.size() - pos_) +
             " left (message of " + std::to_string(bytes_.size()) + " bytes is truncated)");
  }
  pos_ += pad;
}

uint8_t CdrReader::U8(const char* field) {
  Need(field, 1, 1);
  return bytes_[pos_++];
}

bool CdrReader::Bool(const char* field) {
  Need(field, 1, 1);
  const uint8_t b = bytes_[pos_];
  if (b > 1) Fail(field, pos_, "bool byte is " + std::to_string(b) + ", not 0 or 1");
  ++pos_;
  return b == 1;
}

int32_t CdrReader::I32(const char* field) {
  Need(field, 4, 4);
  int32_t v;
  std::memcpy(&v, bytes_.data() + pos_, 4);
  pos_ += 4;
  return v;
}

uint32_t CdrReader::U32(const char* field) {
  Need(field, 4, 4);
  uint32_t v;
  std::memcpy(&v, bytes_.data() + pos_, 4);
  pos_ += 4;
  return v;
}

float CdrReader::F32(const char* field) {
  Need(field, 4, 4);
  float v;
  std::memcpy(&v, bytes_.data() + pos_, 4);
  pos_ += 4;
  return v;
}

double CdrReader::F64(const char* field) {
  Need(field, 8, 8);
  double v;
  std::memcpy(&v, bytes_.data() + pos_, 8);
  pos_ += 8;
  return v;
}

std::string CdrReader::String(const char* field) {
  const size_t at = pos_;
  const uint32_t n = U32(field);
  if (n == 0) Fail(field, at, "string length 0 (it must count the terminating NUL)");
  if (n > bytes_.size() - pos_) {
    Fail(field, at,
         "string length " + std::to_string(n) + " runs past the end (" +
             std::to_string(bytes_.size() - pos_) + " bytes left)");
  }
  const char* p = reinterpret_cast<const char*>(bytes_.data() + pos_);
  if (p[n - 1] != '\0') Fail(field, pos_ + n - 1, "string does not end in NUL");
  std::string s(p, n - 1);
  if (s.find('\0') != std::string::npos) Fail(field, pos_, "string holds a NUL before its end");
  pos_ += n;
  return s;
}

uint32_t CdrReader::SequenceLength(const char* field, size_t min_element_bytes) {
  const size_t at = pos_;
  const uint32_t n = U32(field);
  const size_t left = bytes_.size() - pos_;
  if (min_element_bytes == 0) min_element_bytes = 1;
  if (n > left / min_element_bytes) {
    Fail(field, at,
         "sequence of " + std::to_string(n) + " elements (at least " +
             std::to_string(min_element_bytes) + " bytes each) cannot fit in the " +
             std::to_string(left) + " bytes left");
  }
  return n;
}

void CdrReader::SkipBytes(const char* field, size_t n) {
  Need(field, 1, n);
  pos_ += n;
}

void CdrReader::Finish() {
  const size_t left = bytes_.size() - pos_;
  if (left > 3) {
    Fail("(end)", pos_,
         std::to_string(left) + " bytes left after the last field (at most 3 bytes of padding)");
  }
}

}  // namespace felt::ros2
