#include "exodaq/drivers/sim_rig.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace exodaq::drivers::sim {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kLimitSlack = 1e-12;

std::size_t u(int j) noexcept {
  return static_cast<std::size_t>(j);
}

std::uint64_t splitmix64(std::uint64_t x) noexcept {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

// floor(a / b) for b > 0.
std::int64_t floor_div(std::int64_t a, std::int64_t b) noexcept {
  std::int64_t q = a / b;
  if ((a % b != 0) && (a < 0)) --q;
  return q;
}

[[noreturn]] void bad(const std::string& what) {
  throw std::invalid_argument("sim: " + what);
}

// Sequential random stream for building the trajectory.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) noexcept : state_(splitmix64(seed ^ 0x5EED5EED5EEDULL)) {}
  double uniform(double lo, double hi) noexcept {
    state_ = splitmix64(state_);
    return lo + (hi - lo) * static_cast<double>(state_ >> 11) * 0x1.0p-53;
  }

 private:
  std::uint64_t state_;
};

}  // namespace

double unit_random(std::uint64_t seed, std::uint64_t stream, std::uint64_t k) noexcept {
  const std::uint64_t h = splitmix64(splitmix64(seed ^ (stream * 0xD1B54A32D192ED03ULL)) ^ k);
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

// ---------------------------------------------------------------------------
// SimMotion
// ---------------------------------------------------------------------------

SimMotion::SimMotion(const SimMotionOptions& o, const Vec6& index_angle_rad,
                     const Vec6& index_period_rad)
    : options_(o) {
  for (int j = 0; j < kJoints; ++j) {
    const std::string jn = "joint " + std::to_string(j + 1) + ": ";
    const double lo = o.lower_limit_rad[u(j)];
    const double hi = o.upper_limit_rad[u(j)];
    if (!(lo < hi)) bad(jn + "lower limit not below upper limit");
    if (o.home_rad[u(j)] < lo || o.home_rad[u(j)] > hi) bad(jn + "home outside the limits");
    if (o.task_lower_rad[u(j)] < lo - kLimitSlack || o.task_upper_rad[u(j)] > hi + kLimitSlack ||
        o.task_lower_rad[u(j)] > o.task_upper_rad[u(j)]) {
      bad(jn + "task window outside the limits");
    }
    if (o.home_rad[u(j)] < o.task_lower_rad[u(j)] || o.home_rad[u(j)] > o.task_upper_rad[u(j)]) {
      bad(jn + "home outside the task window");
    }
    if (!(o.speed_cap_rad_s[u(j)] > 0)) bad(jn + "speed cap must be positive");
    if (!(index_period_rad[u(j)] > 0)) bad(jn + "index period must be positive");
  }
  if (!(o.min_segment_s > 0) || !(o.homing_speed_rad_s > 0) || o.duration_slack < 0 ||
      o.start_hold_s < 0 || o.grasp_hold_s < 0 || o.feed_hold_s < 0 || o.home_hold_s < 0 ||
      o.round_trips < 1) {
    bad("motion durations, speeds and round_trips must be positive");
  }

  Rng rng(o.seed);
  auto move_duration = [&](const Vec6& a, const Vec6& b, const Vec6& cap) {
    double t = o.min_segment_s;
    for (int j = 0; j < kJoints; ++j) {
      t = std::max(t, 1.875 * std::abs(b[u(j)] - a[u(j)]) / cap[u(j)]);
    }
    return t * (1.0 + rng.uniform(0.0, o.duration_slack));
  };
  auto push = [](std::vector<Segment>& segs, double& t, double dur, const Vec6& a, const Vec6& b) {
    segs.push_back(Segment{t, dur, a, b});
    t += dur;
  };

  // Homing: each joint in turn past its index (nearest index instance to home).
  double t = 0.0;
  const Vec6& home = o.home_rad;
  if (o.start_hold_s > 0) push(homing_, t, o.start_hold_s, home, home);
  Vec6 homing_cap;
  homing_cap.fill(o.homing_speed_rad_s);
  for (int j = 0; j < kJoints; ++j) {
    const double period = index_period_rad[u(j)];
    const double n = std::round((home[u(j)] - index_angle_rad[u(j)]) / period);
    const double idx = index_angle_rad[u(j)] + n * period;
    homing_index_[u(j)] = idx;
    if (!o.homing) continue;
    const double dir = idx >= home[u(j)] ? 1.0 : -1.0;
    Vec6 target = home;
    target[u(j)] = idx + dir * o.homing_overshoot_rad;
    if (target[u(j)] < o.lower_limit_rad[u(j)] || target[u(j)] > o.upper_limit_rad[u(j)]) {
      bad("joint " + std::to_string(j + 1) +
          ": the homing sweep past the index would leave the joint limits");
    }
    push(homing_, t, move_duration(home, target, homing_cap), home, target);
    push(homing_, t, move_duration(target, home, homing_cap), target, home);
  }
  homing_end_s_ = t;

  // Round trips. Waypoints as fractions of each joint's task window.
  struct Range {
    double lo, hi;
  };
  constexpr std::array<Range, kJoints> kReach{
      {{0.5, 1.0}, {0.0, 1.0}, {0.0, 0.35}, {0.3, 0.7}, {0.75, 1.0}, {0.3, 0.7}}};
  constexpr std::array<Range, kJoints> kFeed{
      {{0.0, 0.5}, {0.0, 1.0}, {0.5, 0.9}, {0.5, 1.0}, {0.0, 0.25}, {0.0, 0.3}}};
  auto waypoint = [&](const std::array<Range, kJoints>& r) {
    Vec6 w;
    for (int j = 0; j < kJoints; ++j) {
      const double lo = o.task_lower_rad[u(j)];
      const double hi = o.task_upper_rad[u(j)];
      w[u(j)] = lo + (hi - lo) * rng.uniform(r[u(j)].lo, r[u(j)].hi);
    }
    return w;
  };
  t = 0.0;
  for (int trip = 0; trip < o.round_trips; ++trip) {
    const Vec6 reach = waypoint(kReach);
    Vec6 grasp = reach;  // a small adjustment around the reach posture
    for (int j = 0; j < kJoints; ++j) {
      const double lo = o.task_lower_rad[u(j)];
      const double hi = o.task_upper_rad[u(j)];
      grasp[u(j)] = std::clamp(reach[u(j)] + (hi - lo) * rng.uniform(-0.1, 0.1), lo, hi);
    }
    const Vec6 feed = waypoint(kFeed);
    const Vec6& cap = o.speed_cap_rad_s;
    push(trips_, t, move_duration(home, reach, cap), home, reach);
    push(trips_, t, move_duration(reach, grasp, cap), reach, grasp);
    push(trips_, t, o.grasp_hold_s * (1.0 + rng.uniform(0.0, 0.5)), grasp, grasp);
    push(trips_, t, move_duration(grasp, feed, cap), grasp, feed);
    push(trips_, t, o.feed_hold_s * (1.0 + rng.uniform(0.0, 0.5)), feed, feed);
    push(trips_, t, move_duration(feed, home, cap), feed, home);
    push(trips_, t, o.home_hold_s * (1.0 + rng.uniform(0.0, 0.5)), home, home);
  }
  cycle_s_ = t;
}

JointTruth SimMotion::eval(const Segment& s, double t) noexcept {
  JointTruth out;
  double tau = (t - s.t0) / s.duration;
  tau = std::clamp(tau, 0.0, 1.0);
  const double t2 = tau * tau;
  const double t3 = t2 * tau;
  const double pos = t3 * (10.0 + tau * (-15.0 + 6.0 * tau));
  const double vel = 30.0 * t2 * (1.0 - 2.0 * tau + t2) / s.duration;
  const double acc = 60.0 * tau * (1.0 - 3.0 * tau + 2.0 * t2) / (s.duration * s.duration);
  for (std::size_t j = 0; j < kJoints; ++j) {
    const double d = s.to[j] - s.from[j];
    out.position[j] = d == 0.0 ? s.from[j] : s.from[j] + d * pos;
    out.velocity[j] = d * vel;
    out.acceleration[j] = d * acc;
  }
  return out;
}

const SimMotion::Segment* SimMotion::find(const std::vector<Segment>& segs, double t) noexcept {
  // Last segment with t0 <= t.
  auto it = std::upper_bound(segs.begin(), segs.end(), t,
                             [](double v, const Segment& s) { return v < s.t0; });
  if (it == segs.begin()) return &segs.front();
  return &*(it - 1);
}

JointTruth SimMotion::truth(double t) const noexcept {
  if (t <= 0.0 || (t < homing_end_s_ && homing_.empty())) {
    JointTruth rest;
    rest.position = options_.home_rad;
    return rest;
  }
  if (t < homing_end_s_) return eval(*find(homing_, t), t);
  const double r = std::fmod(t - homing_end_s_, cycle_s_);
  return eval(*find(trips_, r), r);
}

// ---------------------------------------------------------------------------
// SimEncoders
// ---------------------------------------------------------------------------

SimEncoders::SimEncoders(const std::array<SimEncoderParams, kJoints>& params,
                         const Vec6& initial_rad)
    : params_(params) {
  std::uint32_t channels = 0;
  for (int j = 0; j < kJoints; ++j) {
    const SimEncoderParams& p = params_[u(j)];
    const std::string jn = "joint " + std::to_string(j + 1) + ": ";
    if (p.channel < 0 || p.channel >= kChannelCount) bad(jn + "channel outside 0..5");
    channels |= 1U << p.channel;
    if (p.direction != 1 && p.direction != -1) bad(jn + "direction must be +1 or -1");
    if (p.counts_per_rev <= 0) bad(jn + "counts per revolution must be positive");
    if (!(p.gear_ratio > 0)) bad(jn + "gear ratio must be positive");
  }
  if (channels != 0x3F) bad("encoder channels must use each of 0..5 once");
  for (int j = 0; j < kJoints; ++j) {
    const SimEncoderParams& p = params_[u(j)];
    f_[u(j)] = whole_counts(j, initial_rad[u(j)]);
    offset_[u(j)] = p.power_up_count - p.direction * f_[u(j)];
    count_[u(j)] = p.power_up_count;
  }
}

double SimEncoders::encoder_position(int j, double theta) const noexcept {
  const SimEncoderParams& p = params_[u(j)];
  return (theta - p.index_angle_rad) * static_cast<double>(p.counts_per_rev) * p.gear_ratio /
         kTwoPi;
}

std::int64_t SimEncoders::whole_counts(int j, double theta) const noexcept {
  return static_cast<std::int64_t>(std::floor(encoder_position(j, theta)));
}

std::int64_t SimEncoders::count_at(int j, double theta) const noexcept {
  return params_[u(j)].direction * whole_counts(j, theta) + offset_[u(j)];
}

std::int64_t SimEncoders::count_at_index(int j, std::int64_t n) const noexcept {
  const SimEncoderParams& p = params_[u(j)];
  return p.direction * n * p.counts_per_rev + offset_[u(j)];
}

void SimEncoders::update(const Vec6& theta) noexcept {
  for (int j = 0; j < kJoints; ++j) {
    const std::int64_t cpr = params_[u(j)].counts_per_rev;
    const std::int64_t f = whole_counts(j, theta[u(j)]);
    const std::int64_t r_prev = floor_div(f_[u(j)], cpr);
    const std::int64_t r_now = floor_div(f, cpr);
    latched_[u(j)] = r_now != r_prev;
    if (r_now > r_prev) latched_count_[u(j)] = count_at_index(j, r_now);      // crossed upward
    if (r_now < r_prev) latched_count_[u(j)] = count_at_index(j, r_now + 1);  // downward
    f_[u(j)] = f;
    count_[u(j)] = params_[u(j)].direction * f + offset_[u(j)];
  }
}

// ---------------------------------------------------------------------------
// SimBoard
// ---------------------------------------------------------------------------

int SimBoard::make_cycle(std::int64_t k, const BoardCycle& c, Frames& out) const noexcept {
  const auto seq = static_cast<std::uint8_t>((options_.first_seq + k) & 0xFF);
  int n = 0;
  for (int ch = 0; ch < kChannelCount; ++ch) {
    if ((c.index_latched & (1U << ch)) != 0) {
      out[u(n++)] = can::encode_index(ch, static_cast<std::uint16_t>(c.index_count[u(ch)] & 0xFFFF),
                                      seq, options_.ids);
    }
  }
  for (int which = 0; which < 2; ++which) {
    std::array<std::uint16_t, can::kChannelsPerCountsFrame> v{};
    for (int i = 0; i < can::kChannelsPerCountsFrame; ++i) {
      v[u(i)] = static_cast<std::uint16_t>(c.count[u(3 * which + i)] & 0xFFFF);
    }
    const auto latched = static_cast<std::uint8_t>((c.index_latched >> (3 * which)) & 0x07);
    out[u(n++)] = can::encode_counts(which, v, latched, seq, options_.ids);
  }
  if (options_.heartbeat_every > 0 && k % options_.heartbeat_every == 0) {
    can::HeartbeatPayload hb;
    hb.state = options_.state;
    hb.errors = options_.errors;
    hb.channel_quadrature_errors = options_.channel_quadrature_errors;
    hb.protocol_version = can::kProtocolVersion;
    out[u(n++)] = can::encode_heartbeat(hb, 4, options_.ids);
  }
  return n;
}

// ---------------------------------------------------------------------------
// SimRig
// ---------------------------------------------------------------------------

namespace {

SimMotionOptions seeded(const SimOptions& o) {
  SimMotionOptions m = o.motion;
  m.seed = o.seed;
  return m;
}

Vec6 index_angles(const SimOptions& o) {
  Vec6 v;
  for (int j = 0; j < kJoints; ++j) v[u(j)] = o.encoders[u(j)].index_angle_rad;
  return v;
}

Vec6 index_periods(const SimOptions& o) {
  Vec6 v;
  for (int j = 0; j < kJoints; ++j) {
    const double g = o.encoders[u(j)].gear_ratio;
    v[u(j)] = g > 0 ? kTwoPi / g : 0.0;  // 0 is rejected by SimMotion
  }
  return v;
}

const SimOptions& checked(const SimOptions& o) {
  if (o.period_ns <= 0) bad("period must be positive");
  if (!(o.loss_percent >= 0 && o.loss_percent <= 100)) bad("loss_percent outside 0..100");
  if (!(o.partial_percent >= 0 && o.partial_percent <= 100)) bad("partial_percent outside 0..100");
  if (o.jitter_ns < 0) bad("jitter must not be negative");
  if (const char* why = can::validate(o.board.ids)) bad(why);
  return o;
}

}  // namespace

SimRig::SimRig(const SimOptions& options)
    : options_(checked(options)),
      motion_(seeded(options), index_angles(options), index_periods(options)),
      encoders_(options.encoders, motion_.position(0.0)),
      board_(options.board),
      base_errors_(options.board.errors) {
  for (const SimFault& f : options_.faults) {
    if (f.joint < 0 || f.joint >= kJoints) bad("fault: joint must be 0..5");
    if (f.start_s < 0.0) bad("fault: start_s must be >= 0");
    if (f.percent < 0.0 || f.percent > 100.0) bad("fault: percent must be in [0, 100]");
  }
  options_.jitter_ns = std::min(options_.jitter_ns, (options_.period_ns - 1) / 2);
}

std::int64_t SimRig::fault_count_offset(int j, double t_s, std::int64_t k) const noexcept {
  std::int64_t offset = 0;
  for (const SimFault& f : options_.faults) {
    if (f.joint != j || t_s < f.start_s) continue;
    switch (f.kind) {
      case SimFault::Kind::kCountOffset:
        offset += f.counts;
        break;
      case SimFault::Kind::kCountRamp: {
        // One count per cycle: k cycles since the start cycle.
        const auto start_k = static_cast<std::int64_t>(
            std::ceil(f.start_s * 1e9 / static_cast<double>(options_.period_ns)));
        const std::int64_t n = std::min<std::int64_t>(k - start_k + 1, std::llabs(f.counts));
        offset += f.counts >= 0 ? std::max<std::int64_t>(n, 0) : -std::max<std::int64_t>(n, 0);
        break;
      }
      default:
        break;
    }
  }
  return offset;
}

double SimRig::fault_excursion_rad(int j, double t_s) const noexcept {
  double angle = 0.0;
  for (const SimFault& f : options_.faults) {
    if (f.kind != SimFault::Kind::kExcursion || f.joint != j || t_s < f.start_s) continue;
    const double into = t_s - f.start_s;
    if (f.duration_s <= 0.0 || into >= f.duration_s) continue;
    const double x = into / f.duration_s;  // 0..1: out the first half, back the second
    const double shape = x < 0.5 ? 2.0 * x : 2.0 * (1.0 - x);
    const auto& e = encoders_.params(j);
    angle += shape * static_cast<double>(f.counts) * 2.0 * std::numbers::pi /
             (static_cast<double>(e.counts_per_rev) * e.gear_ratio);
  }
  return angle;
}

std::int64_t SimRig::sample_offset_ns(std::int64_t k) const noexcept {
  std::int64_t t = k * options_.period_ns;
  if (options_.jitter_ns > 0) {
    const double r = unit_random(options_.seed, 1, static_cast<std::uint64_t>(k));
    t += static_cast<std::int64_t>(
        std::llround((2.0 * r - 1.0) * static_cast<double>(options_.jitter_ns)));
  }
  return t;
}

bool SimRig::cycle_lost(std::int64_t k) const noexcept {
  return options_.loss_percent > 0 &&
         unit_random(options_.seed, 2, static_cast<std::uint64_t>(k)) * 100.0 <
             options_.loss_percent;
}

bool SimRig::cycle_partial(std::int64_t k) const noexcept {
  return options_.partial_percent > 0 &&
         unit_random(options_.seed, 3, static_cast<std::uint64_t>(k)) * 100.0 <
             options_.partial_percent;
}

int SimRig::step(std::int64_t k, SimBoard::Frames& out, std::int64_t start_mono_ns,
                 std::int64_t wall_offset_ns) noexcept {
  const std::int64_t t_ns = sample_offset_ns(k);
  // The joints where they really are: the motion plus any scripted excursion.
  Vec6 theta = motion_.position(static_cast<double>(t_ns) * 1e-9);
  for (int j = 0; j < kJoints; ++j)
    theta[u(j)] += fault_excursion_rad(j, static_cast<double>(t_ns) * 1e-9);
  encoders_.update(theta);
  BoardCycle c;
  for (int j = 0; j < kJoints; ++j) {
    const auto ch = u(encoders_.params(j).channel);
    c.count[ch] = encoders_.count(j);
    if (encoders_.latched(j)) {
      c.index_latched |= 1U << ch;
      c.index_count[ch] = encoders_.latched_count(j);
    }
  }
  // Scripted faults (SimOptions::faults).
  const double t_s = static_cast<double>(t_ns) * 1e-9;
  bool silent = false;
  bool dropped = false;
  bool partial = false;
  bool duplicate = false;
  bool hold_counts = false;
  bool bad_seq = false;
  bool wrong_dlc = false;
  std::uint8_t errors = base_errors_;
  std::array<bool, kJoints> stuck{};
  for (const SimFault& f : options_.faults) {
    const bool active = t_s >= f.start_s && (f.duration_s <= 0.0 || t_s < f.start_s + f.duration_s);
    if (!active) continue;
    switch (f.kind) {
      case SimFault::Kind::kStuck:
        stuck[u(f.joint)] = true;
        break;
      case SimFault::Kind::kSilence:
        silent = true;
        break;
      case SimFault::Kind::kDrop:
        dropped = dropped ||
                  unit_random(options_.seed, 4, static_cast<std::uint64_t>(k)) * 100.0 < f.percent;
        break;
      case SimFault::Kind::kPartial:
        partial = true;
        break;
      case SimFault::Kind::kDuplicate:
        duplicate = true;
        break;
      case SimFault::Kind::kBoardError:
        errors = static_cast<std::uint8_t>(errors | f.error_bits);
        break;
      case SimFault::Kind::kReorder: {
        // Cycles start_k, start_k + 2, ...: held back; the cycle after each goes first.
        const auto start_k = static_cast<std::int64_t>(
            std::ceil(f.start_s * 1e9 / static_cast<double>(options_.period_ns)));
        hold_counts = hold_counts || (k - start_k) % 2 == 0;
        break;
      }
      case SimFault::Kind::kBadSeq:
        bad_seq = true;
        break;
      case SimFault::Kind::kWrongDlc:
        wrong_dlc = true;
        break;
      default:
        break;
    }
  }
  for (int j = 0; j < kJoints; ++j) {
    const auto ch = u(encoders_.params(j).channel);
    const std::int64_t offset = fault_count_offset(j, t_s, k);
    c.count[ch] += offset;
    c.index_count[ch] += offset;
    if (stuck[u(j)]) {
      if (!stuck_[u(j)]) stuck_count_[u(j)] = c.count[ch];
      c.count[ch] = stuck_count_[u(j)];
      c.index_latched &= ~(1U << ch);  // a dead channel latches nothing
    }
    stuck_[u(j)] = stuck[u(j)];
  }
  board_.options().errors = errors;

  int n = board_.make_cycle(k, c, out);
  if (cycle_lost(k) || silent || dropped) {
    held_n_ = 0;  // whatever was held back is lost with the cycle
    return 0;
  }
  const std::uint32_t id_a = board_.options().ids.counts_a_id();
  const std::uint32_t id_b = board_.options().ids.counts_b_id();
  for (int i = 0; i < n; ++i) {
    can::CanFrame& f = out[u(i)];
    if (bad_seq && (f.id == id_a || f.id == id_b)) {
      f.data[7] = static_cast<std::uint8_t>(f.data[7] + 128);
    }
    if (wrong_dlc && f.id == id_b) f.dlc = 6;
  }
  if (duplicate && n < static_cast<int>(out.size())) {
    const std::uint32_t a = board_.options().ids.counts_a_id();
    for (int i = 0; i < n; ++i) {
      if (out[u(i)].id == a) {
        for (int m = n; m > i + 1; --m) out[u(m)] = out[u(m - 1)];
        out[u(i + 1)] = out[u(i)];
        ++n;
        break;
      }
    }
  }
  if (cycle_partial(k) || partial) {  // drop COUNTS_B
    const std::uint32_t b = board_.options().ids.counts_b_id();
    int w = 0;
    for (int i = 0; i < n; ++i) {
      if (out[u(i)].id != b) out[u(w++)] = out[u(i)];
    }
    n = w;
  }
  // kReorder: this cycle's count frames wait for the next cycle; the ones
  // held back from the previous cycle follow this cycle's.
  std::array<can::CanFrame, 2> late{};
  const int late_n = held_n_;
  for (int i = 0; i < late_n; ++i) late[u(i)] = held_[u(i)];
  held_n_ = 0;
  if (hold_counts) {
    int w = 0;
    for (int i = 0; i < n; ++i) {
      const can::CanFrame& f = out[u(i)];
      if ((f.id == id_a || f.id == id_b) && held_n_ < static_cast<int>(held_.size())) {
        held_[u(held_n_++)] = f;
      } else {
        out[u(w++)] = f;
      }
    }
    n = w;
  }
  for (int i = 0; i < late_n && n < static_cast<int>(out.size()); ++i) out[u(n++)] = late[u(i)];
  const std::int64_t mono = start_mono_ns + t_ns;
  for (int i = 0; i < n; ++i) {
    out[u(i)].mono_ns = mono;
    out[u(i)].wall_ns = mono + wall_offset_ns;
  }
  return n;
}

std::span<const SimFaultName> sim_fault_names() noexcept {
  using K = SimFault::Kind;
  static constexpr SimFaultName kNames[] = {
      {K::kCountOffset, "glitch"}, {K::kCountRamp, "lost_counts"}, {K::kExcursion, "excursion"},
      {K::kStuck, "stuck"},        {K::kSilence, "silence"},       {K::kDrop, "drop"},
      {K::kPartial, "partial"},    {K::kDuplicate, "duplicate"},   {K::kBoardError, "board_error"},
      {K::kReorder, "reorder"},    {K::kBadSeq, "bad_seq"},        {K::kWrongDlc, "wrong_dlc"},
      {K::kStall, "stall"},
  };
  return kNames;
}

std::string_view sim_fault_name(SimFault::Kind kind) noexcept {
  for (const SimFaultName& n : sim_fault_names()) {
    if (n.kind == kind) return n.name;
  }
  return "?";
}

}  // namespace exodaq::drivers::sim
