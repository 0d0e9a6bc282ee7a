#pragma once
// Deterministic mutations of good input files, for the tests that every bad file gets a clean
// error (README: "Bad input always gets a clear error that names what was wrong"). Each mutant
// applies one to three edits drawn from a seeded generator, so a failure names its seed and can
// be replayed exactly.

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "tests/test_env.h"

namespace felt::test {

/// How many mutants a test makes: FELT_MUTANTS=N when set (a longer search by hand), else
/// `release`, or `sanitized` under a sanitizer (the same code paths, checked byte by byte).
inline int MutantCount(int release, int sanitized) {
  if (const char* n = std::getenv("FELT_MUTANTS"); n != nullptr && *n != '\0') return std::atoi(n);
  return testing::Sanitized() ? sanitized : release;
}

/// Numbers a hand-edited or corrupted file may hold where a normal value stood.
inline constexpr std::array<std::string_view, 22> kHostileNumbers = {
    "nan",        "inf",
    "-inf",       "1e308",
    "-1e308",     "1e400",
    "0",          "-0",
    "-1",         "1e-320",
    "1e12",       "-1e12",
    "1e20",       "",
    "4294967296", "99999999999999999999999",
    "0x10",       "1e",
    "3.5.1",      "+",
    "2147483648", "-9223372036854775809"};

/// Makes mutants of one input.
class Mutator {
 public:
  /// `seed` fixes every mutant this mutator makes.
  explicit Mutator(uint64_t seed) : rng_(seed) {}

  /// A mutant of binary input: bit flips, bytes set, ranges deleted, duplicated or filled with
  /// random bytes, the file truncated, or a 32- or 64-bit field set to 0, all ones or the top bit.
  std::string Bytes(std::string in) {
    const int edits = 1 + static_cast<int>(Below(3));
    for (int e = 0; e < edits; ++e) in = BytesOnce(std::move(in));
    return in;
  }

  /// A mutant of text input: a number-like token replaced by a hostile number, a line deleted,
  /// duplicated, swapped with another or cut short, a field separator dropped or added, or one of
  /// Bytes' edits.
  std::string Text(std::string in) {
    const int edits = 1 + static_cast<int>(Below(3));
    for (int e = 0; e < edits; ++e) in = TextOnce(std::move(in));
    return in;
  }

 private:
  uint64_t Below(uint64_t n) { return n == 0 ? 0 : rng_() % n; }

  std::string BytesOnce(std::string in) {
    if (in.empty()) return std::string(1 + Below(8), static_cast<char>(Below(256)));
    const size_t at = Below(in.size());
    const size_t len = 1 + Below(std::min<size_t>(64, in.size() - at));
    switch (Below(8)) {
      case 0:
        in[at] = static_cast<char>(in[at] ^ (1u << Below(8)));
        break;
      case 1:
        in[at] = static_cast<char>(Below(256));
        break;
      case 2:
        in.erase(at, len);
        break;
      case 3:
        in.insert(at, in.substr(at, len));
        break;
      case 4:
        for (size_t k = 0; k < len; ++k)
          in.insert(in.begin() + static_cast<ptrdiff_t>(at), static_cast<char>(Below(256)));
        break;
      case 5:
        in.resize(at);
        break;
      case 6: {  // eight bytes set to a hostile double, as a corrupt number field holds
        constexpr std::array<double, 6> kHostile = {std::numeric_limits<double>::quiet_NaN(),
                                                    std::numeric_limits<double>::infinity(),
                                                    -std::numeric_limits<double>::infinity(),
                                                    1e308,
                                                    -1e308,
                                                    4.9e-324};
        if (at + 8 > in.size()) break;
        const double value = kHostile[Below(kHostile.size())];
        std::memcpy(in.data() + at, &value, 8);
        break;
      }
      default: {
        const size_t width = Below(2) == 0 ? 4 : 8;
        if (at + width > in.size()) break;
        const int kind = static_cast<int>(Below(3));
        for (size_t k = 0; k < width; ++k) {
          const bool top = k + 1 == width;
          in[at + k] = kind == 0 ? '\0' : kind == 1 ? '\xff' : (top ? '\x80' : '\0');
        }
        break;
      }
    }
    return in;
  }

  std::string TextOnce(std::string in) {
    std::vector<std::string> lines = SplitLines(in);
    if (lines.empty()) return BytesOnce(std::move(in));
    const size_t l = Below(lines.size());
    switch (Below(8)) {
      case 0:
      case 1:
      case 2: {  // a number-like token replaced
        std::string& line = lines[l];
        std::vector<std::pair<size_t, size_t>> tokens;
        for (size_t i = 0; i < line.size();) {
          if (IsNumberChar(line[i])) {
            size_t j = i;
            while (j < line.size() && IsNumberChar(line[j])) ++j;
            tokens.emplace_back(i, j - i);
            i = j;
          } else {
            ++i;
          }
        }
        std::erase_if(tokens, [&](const std::pair<size_t, size_t>& t) {
          return std::none_of(line.begin() + static_cast<ptrdiff_t>(t.first),
                              line.begin() + static_cast<ptrdiff_t>(t.first + t.second),
                              [](char c) { return c >= '0' && c <= '9'; });
        });
        if (tokens.empty()) return BytesOnce(std::move(in));
        const auto [pos, n] = tokens[Below(tokens.size())];
        line.replace(pos, n, kHostileNumbers[Below(kHostileNumbers.size())]);
        break;
      }
      case 3:
        lines.erase(lines.begin() + static_cast<ptrdiff_t>(l));
        break;
      case 4:
        lines.insert(lines.begin() + static_cast<ptrdiff_t>(l), lines[l]);
        break;
      case 5:
        std::swap(lines[l], lines[Below(lines.size())]);
        break;
      case 6:
        lines[l].resize(Below(lines[l].size() + 1));
        break;
      default: {  // a separator dropped or doubled
        std::string& line = lines[l];
        const size_t sep = line.find_first_of(",= \t", Below(line.size() + 1));
        if (sep == std::string::npos) return BytesOnce(std::move(in));
        if (Below(2) == 0) {
          line.erase(sep, 1);
        } else {
          line.insert(sep, 1, line[sep]);
        }
        break;
      }
    }
    std::string out;
    for (size_t i = 0; i < lines.size(); ++i) {
      out += lines[i];
      if (i + 1 < lines.size() || (!in.empty() && in.back() == '\n')) out += '\n';
    }
    return out;
  }

  static bool IsNumberChar(char c) {
    return (c >= '0' && c <= '9') || c == '.' || c == '-' || c == '+' || c == 'e' || c == 'E';
  }

  static std::vector<std::string> SplitLines(const std::string& in) {
    std::vector<std::string> lines;
    size_t start = 0;
    while (start < in.size()) {
      const size_t end = in.find('\n', start);
      if (end == std::string::npos) {
        lines.push_back(in.substr(start));
        break;
      }
      lines.push_back(in.substr(start, end - start));
      start = end + 1;
    }
    return lines;
  }

  std::mt19937_64 rng_;
};

}  // namespace felt::test
