#pragma once
// The sequence numbers of one stream as a recorder sees them (felt record, in its trace and MCAP
// forms): missing numbers counted as gaps, a number not above the last refused. Plain data, one
// thread.

#include <algorithm>
#include <cstdint>

namespace felt::transport {

/// The last sequence number of a stream and the rule for the next one.
struct SequenceTracker {
  bool have = false;  ///< a number has been seen
  uint64_t last = 0;  ///< the highest number seen

  /// A pointer sample's number: true (it becomes the last; the numbers skipped since the last one
  /// are added to *gaps) when it is above the last, false (counted in *out_of_order) when not.
  bool Accept(uint64_t seq, uint64_t* gaps, uint64_t* out_of_order) {
    if (have && seq <= last) {
      ++*out_of_order;
      return false;
    }
    if (have) *gaps += seq - last - 1;
    have = true;
    last = seq;
    return true;
  }

  /// A force's number: the numbers skipped above the last are added to *gaps; never refused (a
  /// force answering an older sample is still the one the device received); the last is the
  /// highest seen.
  void Note(uint64_t seq, uint64_t* gaps) {
    if (have && seq > last + 1) *gaps += seq - last - 1;
    have = true;
    last = std::max(last, seq);
  }
};

}  // namespace felt::transport
