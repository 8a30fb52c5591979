#pragma once
// Private to the calibration library: the readers' bounded stores. Each keeps
// at most a fixed number of samples; when full, every other kept sample is
// dropped and later samples are taken at twice the spacing, so a stream of
// any length ends evenly thinned within the bound (docs/robustness.md "Memory").
#include <algorithm>
#include <cstdint>
#include <limits>
#include <map>
#include <vector>

#include "exodaq/calibration/inputs.hpp"

namespace exodaq::calibration::detail {

// Encoder samples in time order. A dropped sample's masks go into the kept
// sample before it (so the interval is judged as bad as its worst sample),
// and widest_gap_us keeps the widest recorded gap within each kept interval.
class EncoderStore {
 public:
  explicit EncoderStore(std::size_t cap = kMaxEncoderSamples, std::size_t reserve = 0)
      : cap_(std::max<std::size_t>(cap, 2)) {
    kept_.reserve(std::min(reserve, cap_));
  }

  void push(const EncoderSample& s) {
    if (count_ > 0) widen(kept_.back(), s.utime_us - last_utime_);
    last_utime_ = s.utime_us;
    if (count_++ % stride_ == 0) {
      kept_.push_back(s);
      kept_.back().widest_gap_us = 0;
      if (kept_.size() >= cap_) halve();
    } else {
      merge(kept_.back(), s);
      ++thinned_;
    }
  }
  bool empty() const noexcept { return count_ == 0; }
  std::int64_t last_utime() const noexcept { return last_utime_; }
  std::size_t thinned() const noexcept { return thinned_; }
  std::vector<EncoderSample> take() { return std::move(kept_); }

 private:
  static void widen(EncoderSample& k, std::int64_t gap) {
    const auto g = static_cast<std::int32_t>(
        std::min<std::int64_t>(gap, std::numeric_limits<std::int32_t>::max()));
    k.widest_gap_us = std::max(k.widest_gap_us, g);
  }
  static void merge(EncoderSample& into, const EncoderSample& s) {
    into.homed_mask &= s.homed_mask;
    into.fault_mask |= s.fault_mask;
  }
  void halve() {
    std::size_t w = 0;
    for (std::size_t r = 0; r < kept_.size(); ++r) {
      if (r % 2 == 0) {
        kept_[w++] = kept_[r];
      } else {
        EncoderSample& k = kept_[w - 1];
        merge(k, kept_[r]);
        widen(k, kept_[r].widest_gap_us);
        ++thinned_;
      }
    }
    kept_.resize(w);
    stride_ *= 2;
  }

  std::size_t cap_;
  std::vector<EncoderSample> kept_;
  std::uint64_t count_ = 0, stride_ = 1;
  std::int64_t last_utime_ = 0;
  std::size_t thinned_ = 0;
};

// Marker samples in file order, thinned per marker at one common spacing (so
// markers of one frame stay together when every frame lists every marker).
class MarkerStore {
 public:
  explicit MarkerStore(std::size_t cap = kMaxMarkerSamples) : cap_(std::max<std::size_t>(cap, 2)) {}

  void push(const MarkerSample& s) {
    if (counts_[s.marker_id]++ % stride_ != 0) {
      ++thinned_;
      return;
    }
    kept_.push_back(s);
    if (kept_.size() >= cap_) halve();
  }
  std::size_t thinned() const noexcept { return thinned_; }
  std::vector<MarkerSample> take() { return std::move(kept_); }

 private:
  void halve() {
    std::map<int, std::uint64_t> parity;
    std::size_t w = 0;
    for (const MarkerSample& s : kept_) {
      if (parity[s.marker_id]++ % 2 == 0) {
        kept_[w++] = s;
      } else {
        ++thinned_;
      }
    }
    kept_.resize(w);
    stride_ *= 2;
  }

  std::size_t cap_;
  std::vector<MarkerSample> kept_;
  std::map<int, std::uint64_t> counts_;
  std::uint64_t stride_ = 1;
  std::size_t thinned_ = 0;
};

}  // namespace exodaq::calibration::detail
