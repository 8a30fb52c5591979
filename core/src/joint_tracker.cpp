#include "exodaq/core/joint_tracker.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "exodaq/common/wrapping.hpp"

namespace exodaq::core {

namespace {
constexpr double kTwoPi = 6.283185307179586;

std::int64_t round_div(std::int64_t num, std::int64_t den) noexcept {
  return static_cast<std::int64_t>(
      std::llround(static_cast<double>(num) / static_cast<double>(den)));
}
}  // namespace

JointTracker::JointTracker(const JointTrackerConfig& config) {
  reconfigure(config);
}

void JointTracker::reconfigure(const JointTrackerConfig& config) noexcept {
  const bool geometry_changed =
      config.channel != config_.channel || config.direction != config_.direction ||
      config.counts_per_rev != config_.counts_per_rev || config.gear_ratio != config_.gear_ratio;
  const int vel_window_before = config_.velocity_window;
  config_ = config;
  if (config_.velocity_window < 2) config_.velocity_window = 2;
  if (config_.velocity_window > kMaxVelocityWindow) config_.velocity_window = kMaxVelocityWindow;
  rad_per_count_ = kTwoPi / (static_cast<double>(config_.counts_per_rev) * config_.gear_ratio);
  if (geometry_changed && homing_ == HomingState::kHomed) {
    // A different encoder geometry invalidates the reference: home again.
    homing_ = HomingState::kUnhomed;
  }
  if (vel_n_ > 0 && vel_window_before != config_.velocity_window) {
    // The newest samples that fit the new window, in order.
    const int old_window = vel_window_before;
    std::array<std::int64_t, kMaxVelocityWindow> t{};
    std::array<std::int64_t, kMaxVelocityWindow> c{};
    const int keep = std::min(vel_n_, config_.velocity_window);
    for (int k = 0; k < keep; ++k) {
      const auto i = static_cast<std::size_t>((vel_head_ - keep + k + old_window * 2) % old_window);
      t[static_cast<std::size_t>(k)] = vel_t_[i];
      c[static_cast<std::size_t>(k)] = vel_c_[i];
    }
    vel_t_ = t;
    vel_c_ = c;
    vel_n_ = keep;
    vel_head_ = keep % config_.velocity_window;
    rebuild_fit(fit_t0_, fit_c0_);
  }
}

double JointTracker::angle_of(std::int64_t count) const noexcept {
  if (homing_ == HomingState::kHomed) {
    const std::int64_t counts_from_ref =
        ref_turns_ * config_.counts_per_rev + config_.direction * (count - ref_count_);
    return config_.offset_rad + static_cast<double>(counts_from_ref) * rad_per_count_;
  }
  // Before homing: relative to power-up, with the rig in its home posture.
  return config_.home_rad +
         static_cast<double>(config_.direction * (count - powerup_count_)) * rad_per_count_;
}

void JointTracker::home_on_index(std::int64_t index_count, JointEvent& event) noexcept {
  // With gear ratio g the index repeats every 2pi/g of joint travel. The
  // reference crossing is the one nearest to where the joint is believed to be
  // (home posture plus travel since power-up): unique while the joint was
  // within pi/g of home at power-up, which the rig's spring ensures.
  const double estimate =
      config_.home_rad +
      static_cast<double>(config_.direction * (index_count - powerup_count_)) * rad_per_count_;
  const double turn_rad = static_cast<double>(config_.counts_per_rev) * rad_per_count_;
  const auto turns =
      static_cast<std::int64_t>(std::llround((estimate - config_.offset_rad) / turn_rad));
  const double index_angle = config_.offset_rad + static_cast<double>(turns) * turn_rad;
  if (index_angle < config_.lower_rad - config_.limit_margin_rad ||
      index_angle > config_.upper_rad + config_.limit_margin_rad) {
    homing_ = HomingState::kRejected;
    ++counters_.rejected_homings;
    event = JointEvent::kHomingRejected;
    return;
  }
  homing_ = HomingState::kHomed;
  ref_count_ = index_count;
  ref_turns_ = turns;
  suspect_ = false;
  ++counters_.homings;
  event = JointEvent::kHomed;
}

void JointTracker::home_absolute(JointEvent& event) noexcept {
  const double turn_rad = static_cast<double>(config_.counts_per_rev) * rad_per_count_;
  const double at_zero_turn =
      config_.offset_rad + static_cast<double>(config_.direction * count_) * rad_per_count_;
  homing_ = HomingState::kHomed;
  ref_count_ = 0;
  ref_turns_ =
      static_cast<std::int64_t>(std::llround((config_.home_rad - at_zero_turn) / turn_rad));
  suspect_ = false;
  ++counters_.homings;
  event = JointEvent::kHomed;
}

void JointTracker::resume(const drivers::JointResume& r) noexcept {
  if (!r.counted || have_count_) return;
  resume_pending_ = true;
  resume_count_ = r.count;
  powerup_count_ = r.powerup_count;
  homing_ = r.homing == wire::status::HOMING_HOMED      ? HomingState::kHomed
            : r.homing == wire::status::HOMING_REJECTED ? HomingState::kRejected
                                                        : HomingState::kUnhomed;
  ref_count_ = r.index_count;
  ref_turns_ = r.index_turns;
}

HomingReference JointTracker::homing_reference() const noexcept {
  HomingReference h;
  h.counted = have_count_;
  h.count = count_;
  h.powerup_count = powerup_count_;
  h.homing = homing_;
  h.index_count = ref_count_;
  h.index_turns = ref_turns_;
  h.index_angle_rad = config_.offset_rad + static_cast<double>(ref_turns_) *
                                               static_cast<double>(config_.counts_per_rev) *
                                               rad_per_count_;
  return h;
}

// Bounds on a sample's distance from the anchor that keep every sum exact in
// 128 bits (64 samples: n * sum_tt < 2^109, sum_t * sum_c < 2^101).
constexpr std::int64_t kFitMaxDt = std::int64_t{1} << 48;  // ns: 3.3 days
constexpr std::int64_t kFitMaxDc = std::int64_t{1} << 40;  // counts

void JointTracker::add_to_fit(std::int64_t t_ns, std::int64_t count, int sign) noexcept {
  const std::int64_t dt = t_ns - fit_t0_;
  const std::int64_t dc = count - fit_c0_;
  sum_t_ += sign * dt;
  sum_c_ += sign * dc;
  sum_tt_ += sign * (static_cast<FitSum>(dt) * dt);
  sum_tc_ += sign * (static_cast<FitSum>(dt) * dc);
}

// The sums of the samples in the window, relative to a new anchor; a sample
// beyond the bounds from it (days without a count) leaves the window.
void JointTracker::rebuild_fit(std::int64_t anchor_t_ns, std::int64_t anchor_count) noexcept {
  fit_t0_ = anchor_t_ns;
  fit_c0_ = anchor_count;
  sum_t_ = sum_c_ = 0;
  sum_tt_ = sum_tc_ = 0;
  const int window = config_.velocity_window;
  int kept = 0;
  std::array<std::int64_t, kMaxVelocityWindow> t{};
  std::array<std::int64_t, kMaxVelocityWindow> c{};
  for (int k = vel_n_; k >= 1; --k) {  // oldest first
    const auto i = static_cast<std::size_t>((vel_head_ - k + window * 2) % window);
    if (std::llabs(vel_t_[i] - fit_t0_) >= kFitMaxDt ||
        std::llabs(vel_c_[i] - fit_c0_) >= kFitMaxDc) {
      continue;
    }
    t[static_cast<std::size_t>(kept)] = vel_t_[i];
    c[static_cast<std::size_t>(kept)] = vel_c_[i];
    add_to_fit(vel_t_[i], vel_c_[i], 1);
    ++kept;
  }
  vel_t_ = t;
  vel_c_ = c;
  vel_n_ = kept;
  vel_head_ = kept % window;
}

// The least-squares slope of count over time, n Stc - St Sc over n Stt - St^2,
// exact in integers and rounded once per operand: the same line the former
// two-pass double loop fitted, to within a few ulp (tests/core/test_joint_tracker.cpp).
void JointTracker::update_velocity(std::int64_t t_ns) noexcept {
  const int window = config_.velocity_window;
  if (vel_n_ == 0 || std::llabs(t_ns - fit_t0_) >= kFitMaxDt ||
      std::llabs(count_ - fit_c0_) >= kFitMaxDc) {
    rebuild_fit(t_ns, count_);
  }
  const auto slot = static_cast<std::size_t>(vel_head_);
  if (vel_n_ == window) {
    add_to_fit(vel_t_[slot], vel_c_[slot], -1);  // the oldest leaves
  } else {
    ++vel_n_;
  }
  vel_t_[slot] = t_ns;
  vel_c_[slot] = count_;
  add_to_fit(t_ns, count_, 1);
  vel_head_ = (vel_head_ + 1) % window;
  if (vel_n_ < 2) {
    reading_.velocity_rad_s = 0.0;
    return;
  }
  const FitSum n = vel_n_;
  const FitSum den = n * sum_tt_ - static_cast<FitSum>(sum_t_) * sum_t_;
  const FitSum num = n * sum_tc_ - static_cast<FitSum>(sum_t_) * sum_c_;
  const double slope =
      den > 0 ? static_cast<double>(num) * 1e9 / static_cast<double>(den) : 0.0;  // counts/s
  reading_.velocity_rad_s = config_.direction * slope * rad_per_count_;
}

JointInput joint_input(const drivers::EncoderSample& s, int channel) noexcept {
  const auto c = static_cast<std::size_t>(channel);
  const auto bit = 1U << static_cast<unsigned>(channel);
  JointInput in;
  in.mono_ns = s.mono_ns;
  in.seq = s.seq;
  in.seq_modulus = s.seq_modulus;
  in.fresh = s.present && (s.channel_fresh & bit) != 0;
  in.position = s.position[c];
  in.modulus = s.modulus[c];
  in.index_valid = s.present && (s.index_count_valid & bit) != 0;
  in.index_position = s.index_position[c];
  in.absolute = (s.absolute & bit) != 0;
  in.board_error = (s.flags & drivers::sample_flag::kBoardError) != 0;
  return in;
}

JointEvent JointTracker::update(const JointInput& in) noexcept {
  JointEvent event = JointEvent::kNone;
  const std::int64_t t_ns = in.mono_ns;
  if (in.fresh) {
    take_count(in, event);
  } else if (have_count_ && t_ns - last_fresh_ns_ > config_.stale_ns && !stale_) {
    stale_ = true;
    ++counters_.stale_events;
    if (event == JointEvent::kNone) event = JointEvent::kStale;
  }
  if (in.index_valid && have_count_ && !in.absolute) {
    const std::int64_t index_count = unwrap(count_, in.index_position, in.modulus);
    if (homing_ != HomingState::kHomed) {
      home_on_index(index_count, event);
    } else {
      check_index(t_ns, index_count, event);
    }
  }
  update_reading(t_ns, in.fresh, in.board_error, event);
  return event;
}

std::int64_t JointTracker::interval_since_fresh(const JointInput& in) const noexcept {
  // Receive instants jitter with the bus and the host (a board that sent two
  // cycles back to back after a stall); the source's cycles do not. The
  // longer of the two bounds the motion: a forward step of source cycles.
  const std::int64_t received = in.mono_ns - last_fresh_ns_;
  if (config_.board_period_ns <= 0 || in.seq < 0 || last_fresh_seq_ < 0) return received;
  const std::int64_t cycles = wrapped_delta(last_fresh_seq_, in.seq, in.seq_modulus);
  return std::max(received, cycles > 0 ? cycles * config_.board_period_ns : 0);
}

void JointTracker::take_count(const JointInput& in, JointEvent& event) noexcept {
  if (!have_count_) {
    have_count_ = true;
    if (resume_pending_) {
      count_ = unwrap(resume_count_, in.position, in.modulus);
      resume_pending_ = false;
    } else {
      count_ = in.position;
      powerup_count_ = count_;
      if (in.absolute) home_absolute(event);
    }
  } else {
    const std::int64_t step = unwrap(count_, in.position, in.modulus) - count_;
    const double dt_s = static_cast<double>(interval_since_fresh(in)) * 1e-9;
    // The most counts the joint can physically produce since the last fresh
    // count, plus one count of quantisation.
    const double max_counts = config_.max_speed_rad_s * (dt_s > 0 ? dt_s : 0.0) / rad_per_count_;
    if (in.modulus > 0 && max_counts >= static_cast<double>(in.modulus / 2 - 1)) {
      // So long without a count that the wrapped step could be off by a
      // modulus: the count is unknowable until the next index.
      suspect_ = true;
      event = JointEvent::kUnwrapAmbiguous;
    } else if (static_cast<double>(std::llabs(step)) > max_counts + 1.0) {
      ++counters_.glitches;
      suspect_ = true;
      event = JointEvent::kGlitch;
    }
    count_ += step;
  }
  last_fresh_ns_ = in.mono_ns;
  last_fresh_seq_ = in.seq;
  stale_ = false;
  update_velocity(in.mono_ns);
}

void JointTracker::check_index(std::int64_t t_ns, std::int64_t index_count,
                               JointEvent& event) noexcept {
  const std::int64_t travel = index_count - ref_count_;
  const std::int64_t turns = round_div(travel, config_.counts_per_rev);
  const std::int64_t drift = travel - turns * config_.counts_per_rev;
  counters_.last_index_drift_counts = drift;
  if (std::llabs(drift) > config_.index_tolerance_counts) {
    // Counts were lost or gained: re-home on this index (seed 000 eq. 4).
    ++counters_.lost_count_events;
    ref_turns_ += config_.direction * turns;
    ref_count_ = index_count;
    lost_counts_until_ns_ = t_ns + config_.fault_hold_ns;
    event = JointEvent::kLostCounts;
  }
  suspect_ = false;  // the index has verified (or corrected) the count
}

void JointTracker::update_reading(std::int64_t t_ns, bool fresh, bool board_error,
                                  JointEvent& event) noexcept {
  JointReading& r = reading_;
  r.count = count_;
  r.homing = homing_;
  r.homed = homing_ == HomingState::kHomed;
  r.position_rad = angle_of(count_);
  std::uint32_t flags = 0;
  if (!r.homed) flags |= joint_flag::kUnhomed;
  if (homing_ == HomingState::kRejected) flags |= joint_flag::kHomingRejected;
  if (stale_ || !have_count_) flags |= joint_flag::kStale;
  if (suspect_) flags |= joint_flag::kGlitch;
  if (t_ns < lost_counts_until_ns_) flags |= joint_flag::kLostCounts;
  if (!fresh) flags |= joint_flag::kHeld;
  if (board_error) flags |= joint_flag::kBoardError;
  const bool beyond = r.homed && (r.position_rad < config_.lower_rad - config_.limit_margin_rad ||
                                  r.position_rad > config_.upper_rad + config_.limit_margin_rad);
  if (beyond) {
    flags |= joint_flag::kOutOfRange;
    if (!out_of_range_) {
      ++counters_.out_of_range_events;
      if (event == JointEvent::kNone) event = JointEvent::kOutOfRange;
    }
  }
  out_of_range_ = beyond;
  r.flags = flags;
}

}  // namespace exodaq::core
