#include "exodaq/drivers/sim_rig.hpp"

#include "exodaq/drivers/sim_task.hpp"

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

namespace {

void check_motion_options(const SimMotionOptions& o, const Vec6& index_period_rad) {
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
}

// Builds the segment lists of SimMotion from one random stream (the order of
// draws fixes the trajectory of a seed).
class SegmentBuilder {
 public:
  SegmentBuilder(const SimMotionOptions& o, std::vector<SimMotion::Segment>& out, double t0)
      : o_(o), rng_(o.seed), out_(&out), t_(t0) {}
  Rng& rng() noexcept { return rng_; }
  double time() const noexcept { return t_; }
  void restart(std::vector<SimMotion::Segment>& out) noexcept {
    out_ = &out;
    t_ = 0.0;
  }
  // Shortest duration keeping every joint within `cap`, stretched at random.
  double move_duration(const Vec6& a, const Vec6& b, const Vec6& cap) noexcept {
    double t = o_.min_segment_s;
    for (int j = 0; j < kJoints; ++j) {
      t = std::max(t, 1.875 * std::abs(b[u(j)] - a[u(j)]) / cap[u(j)]);
    }
    return t * (1.0 + rng_.uniform(0.0, o_.duration_slack));
  }
  void push(double duration, const Vec6& a, const Vec6& b) {
    out_->push_back(SimMotion::Segment{t_, duration, a, b});
    t_ += duration;
  }
  void move(const Vec6& a, const Vec6& b, const Vec6& cap) { push(move_duration(a, b, cap), a, b); }
  void hold(const Vec6& at, double base_s) {
    push(base_s * (1.0 + rng_.uniform(0.0, 0.5)), at, at);
  }

 private:
  const SimMotionOptions& o_;
  Rng rng_;
  std::vector<SimMotion::Segment>* out_;
  double t_;
};

// Homing: each joint in turn past its index (the index instance nearest home)
// and back. Returns each joint's swept index angle.
Vec6 build_homing(const SimMotionOptions& o, const Vec6& index_angle_rad,
                  const Vec6& index_period_rad, SegmentBuilder& b) {
  const Vec6& home = o.home_rad;
  if (o.start_hold_s > 0) b.push(o.start_hold_s, home, home);
  Vec6 homing_cap;
  homing_cap.fill(o.homing_speed_rad_s);
  Vec6 index{};
  for (int j = 0; j < kJoints; ++j) {
    const double period = index_period_rad[u(j)];
    const double n = std::round((home[u(j)] - index_angle_rad[u(j)]) / period);
    index[u(j)] = index_angle_rad[u(j)] + n * period;
    if (!o.homing) continue;
    const double dir = index[u(j)] >= home[u(j)] ? 1.0 : -1.0;
    Vec6 target = home;
    target[u(j)] = index[u(j)] + dir * o.homing_overshoot_rad;
    if (target[u(j)] < o.lower_limit_rad[u(j)] || target[u(j)] > o.upper_limit_rad[u(j)]) {
      bad("joint " + std::to_string(j + 1) +
          ": the homing sweep past the index would leave the joint limits");
    }
    b.move(home, target, homing_cap);
    b.move(target, home, homing_cap);
  }
  return index;
}

// The round trips: waypoints as fractions of each joint's task window.
void build_trips(const SimMotionOptions& o, SegmentBuilder& b) {
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
      w[u(j)] = lo + (hi - lo) * b.rng().uniform(r[u(j)].lo, r[u(j)].hi);
    }
    return w;
  };
  const Vec6& home = o.home_rad;
  const Vec6& cap = o.speed_cap_rad_s;
  for (int trip = 0; trip < o.round_trips; ++trip) {
    const Vec6 reach = waypoint(kReach);
    Vec6 grasp = reach;  // a small adjustment around the reach posture
    for (int j = 0; j < kJoints; ++j) {
      const double lo = o.task_lower_rad[u(j)];
      const double hi = o.task_upper_rad[u(j)];
      grasp[u(j)] = std::clamp(reach[u(j)] + (hi - lo) * b.rng().uniform(-0.1, 0.1), lo, hi);
    }
    const Vec6 feed = waypoint(kFeed);
    b.move(home, reach, cap);
    b.move(reach, grasp, cap);
    b.hold(grasp, o.grasp_hold_s);
    b.move(grasp, feed, cap);
    b.hold(feed, o.feed_hold_s);
    b.move(feed, home, cap);
    b.hold(home, o.home_hold_s);
  }
}

}  // namespace

SimMotion::SimMotion(const SimMotionOptions& o, const Vec6& index_angle_rad,
                     const Vec6& index_period_rad)
    : options_(o) {
  check_motion_options(o, index_period_rad);
  SegmentBuilder b(o, homing_, 0.0);
  homing_index_ = build_homing(o, index_angle_rad, index_period_rad, b);
  homing_end_s_ = b.time();
  if (o.task) {  // homing, the lead-in to the task's first stop, then its loop
    plan_ = std::make_shared<const SimTaskPlan>(plan_sim_task(*o.task, o, o.seed));
    for (Segment s : plan_->lead_in) {
      s.t0 += homing_end_s_;
      homing_.push_back(s);
    }
    homing_end_s_ += plan_->lead_in.back().t0 + plan_->lead_in.back().duration;
    trips_ = plan_->loop;
    cycle_s_ = plan_->period_s;
    return;
  }
  b.restart(trips_);
  build_trips(o, b);
  cycle_s_ = b.time();
}

JointTruth SimMotion::eval(const Segment& s, double t) const noexcept {
  if (s.move >= 0) return sample_move(*plan_, s.move, t - s.t0);
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

void check_fault(const SimFault& f, std::int64_t period_ns) {
  const std::string what = "fault " + std::string(sim_fault_name(f.kind)) + ": ";
  if (f.joint < 0 || f.joint >= kJoints) bad(what + "joint must be 1..6");
  if (!(f.start_s >= 0.0)) bad(what + "at_s must be >= 0");
  // A stall blocks the reader for for_s: without one it would block for ever.
  if (f.kind == SimFault::Kind::kStall && !(f.duration_s > 0.0)) bad(what + "for_s must be > 0");
  if (!(f.percent >= 0.0 && f.percent <= 100.0)) bad(what + "percent must be in [0, 100]");
  if (f.every < 1) bad(what + "every must be >= 1");
  if (!(f.delay_us >= 0.0) ||
      f.delay_us * 1000.0 >= static_cast<double>(SimRig::kMaxDelayPeriods * period_ns)) {
    bad(what + "delay_us must be >= 0 and below " + std::to_string(SimRig::kMaxDelayPeriods) +
        " sampling periods");
  }
}

const SimOptions& checked(const SimOptions& o) {
  if (o.period_ns <= 0) bad("period must be positive");
  if (!(o.loss_percent >= 0 && o.loss_percent <= 100)) bad("loss_percent outside 0..100");
  if (!(o.partial_percent >= 0 && o.partial_percent <= 100)) bad("partial_percent outside 0..100");
  if (o.jitter_ns < 0) bad("jitter must not be negative");
  if (!(std::abs(o.board_clock.drift_ppm) <= 1000.0))
    bad("board clock drift must be within ±1000 ppm");
  if (o.board_clock.phase_ns < 0 || o.board_clock.phase_ns >= o.period_ns)
    bad("board clock phase must be in [0, period)");
  if (const char* why = can::validate(o.board.ids)) bad(why);
  for (const SimFault& f : o.faults) check_fault(f, o.period_ns);
  return o;
}

bool in_window(const SimFault& f, double t_s) noexcept {
  return t_s >= f.start_s && (f.duration_s <= 0.0 || t_s < f.start_s + f.duration_s);
}

// Removes frame i from out[0, n), keeping the others' order.
void erase_frame(SimBoard::Frames& out, int& n, int i) noexcept {
  for (int m = i; m + 1 < n; ++m) out[u(m)] = out[u(m + 1)];
  --n;
}

}  // namespace

// What the scripted faults do to one cycle (SimRig::active_faults).
struct SimRig::CycleFaults {
  bool silent = false;
  bool dropped = false;
  bool partial = false;
  bool duplicate = false;
  bool hold_counts = false;  // kReorder
  bool bad_seq = false;
  bool wrong_dlc = false;
  bool error_frame = false;
  std::int64_t delay_ns = 0;
  std::uint8_t errors = 0;
  std::uint8_t quadrature_joints = 0;  // stuck joints whose heartbeat says quadrature error
  std::array<bool, kJoints> stuck{};
  std::uint32_t applied = 0;
};

SimRig::SimRig(const SimOptions& options)
    : options_(checked(options)),
      motion_(seeded(options), index_angles(options), index_periods(options)),
      encoders_(options.encoders, motion_.position(0.0)),
      board_(options.board),
      base_errors_(options.board.errors) {
  options_.jitter_ns = std::min(options_.jitter_ns, (options_.period_ns - 1) / 2);
}

std::int64_t SimRig::start_cycle(const SimFault& f) const noexcept {
  return static_cast<std::int64_t>(
      std::ceil(f.start_s * 1e9 / static_cast<double>(options_.period_ns)));
}

std::int64_t SimRig::fault_count_offset(int j, double t_s, std::int64_t k) const noexcept {
  std::int64_t offset = 0;
  for (const SimFault& f : options_.faults) {
    if (f.joint != j || t_s < f.start_s) continue;
    if (f.kind == SimFault::Kind::kCountOffset) offset += f.counts;
    if (f.kind == SimFault::Kind::kCountRamp) {
      // One count per cycle: k cycles since the start cycle.
      const std::int64_t n =
          std::clamp<std::int64_t>(k - start_cycle(f) + 1, 0, std::llabs(f.counts));
      offset += f.counts >= 0 ? n : -n;
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
    angle += shape * static_cast<double>(f.counts) * kTwoPi /
             (static_cast<double>(e.counts_per_rev) * e.gear_ratio);
  }
  return angle;
}

std::int64_t SimRig::sample_offset_ns(std::int64_t k) const noexcept {
  std::int64_t t = k * options_.period_ns;
  if (const SimBoardClock& b = options_.board_clock; b.free_running) {
    t += b.phase_ns + std::llround(static_cast<double>(k) *
                                   static_cast<double>(options_.period_ns) * b.drift_ppm * 1e-6);
  }
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

SimRig::CycleFaults SimRig::active_faults(std::int64_t k, double t_s) const noexcept {
  using K = SimFault::Kind;
  CycleFaults c;
  c.errors = base_errors_;
  for (const SimFault& f : options_.faults) {
    if (!in_window(f, t_s)) continue;
    const std::int64_t since = k - start_cycle(f);
    const bool nth = since % f.every == 0;  // every-Nth kinds: this cycle is one
    switch (f.kind) {
      case K::kStuck:
        c.stuck[u(f.joint)] = true;
        c.errors = static_cast<std::uint8_t>(c.errors | f.error_bits);
        if ((f.error_bits & can::board_error::kQuadrature) != 0)
          c.quadrature_joints |= 1U << f.joint;
        break;
      case K::kSilence:
        c.silent = true;
        break;
      case K::kDrop:
        c.dropped =
            c.dropped ||
            unit_random(options_.seed, 4, static_cast<std::uint64_t>(k)) * 100.0 < f.percent;
        break;
      case K::kPartial:
        c.partial = true;
        break;
      case K::kDuplicate:
        c.duplicate = c.duplicate || nth;
        break;
      case K::kBoardError:
        c.errors = static_cast<std::uint8_t>(c.errors | f.error_bits);
        c.applied |= fault_bit(K::kBoardError);
        break;
      case K::kReorder:
        c.hold_counts = c.hold_counts || since % 2 == 0;
        break;
      case K::kBadSeq:
        c.bad_seq = c.bad_seq || nth;
        break;
      case K::kWrongDlc:
        c.wrong_dlc = c.wrong_dlc || nth;
        break;
      case K::kDelay:
        c.delay_ns =
            std::max(c.delay_ns, static_cast<std::int64_t>(std::llround(f.delay_us * 1e3)));
        break;
      case K::kErrorFrame:
        c.error_frame = c.error_frame || nth;
        break;
      default:
        break;  // count faults and excursions: per joint, elsewhere
    }
  }
  return c;
}

BoardCycle SimRig::sample_board(double t_s) noexcept {
  // The joints where they really are: the motion plus any scripted excursion.
  Vec6 theta = motion_.position(t_s);
  std::uint32_t excursion = 0;
  for (int j = 0; j < kJoints; ++j) {
    const double e = fault_excursion_rad(j, t_s);
    theta[u(j)] += e;
    if (e != 0.0) excursion = fault_bit(SimFault::Kind::kExcursion);
  }
  encoders_.update(theta);
  cycle_.position = theta;
  cycle_.applied = excursion;
  BoardCycle c;
  for (int j = 0; j < kJoints; ++j) {
    const auto ch = u(encoders_.params(j).channel);
    c.count[ch] = encoders_.count(j);
    if (encoders_.latched(j)) {
      c.index_latched |= 1U << ch;
      c.index_count[ch] = encoders_.latched_count(j);
    }
  }
  cycle_.count = c.count;
  return c;
}

void SimRig::apply_counter_faults(std::int64_t k, double t_s, CycleFaults& f,
                                  BoardCycle& c) noexcept {
  std::uint8_t quadrature_channels = 0;
  for (int j = 0; j < kJoints; ++j) {
    const auto ch = u(encoders_.params(j).channel);
    const std::int64_t offset = fault_count_offset(j, t_s, k);
    c.count[ch] += offset;
    c.index_count[ch] += offset;
    if (offset != 0) {
      for (const SimFault& fault : options_.faults) {
        const bool count_fault =
            fault.kind == SimFault::Kind::kCountOffset || fault.kind == SimFault::Kind::kCountRamp;
        if (count_fault && fault.joint == j && t_s >= fault.start_s)
          f.applied |= fault_bit(fault.kind);
      }
    }
    if (f.stuck[u(j)]) {
      if (!stuck_[u(j)]) stuck_count_[u(j)] = c.count[ch];
      c.count[ch] = stuck_count_[u(j)];
      c.index_latched &= ~(1U << ch);  // a dead channel latches nothing
      f.applied |= fault_bit(SimFault::Kind::kStuck);
      if ((f.quadrature_joints & (1U << j)) != 0) quadrature_channels |= 1U << ch;
    }
    stuck_[u(j)] = f.stuck[u(j)];
  }
  board_.options().errors = f.errors;
  board_.options().channel_quadrature_errors =
      static_cast<std::uint8_t>(options_.board.channel_quadrature_errors | quadrature_channels);
}

int SimRig::reorder(bool hold, SimBoard::Frames& out, int n) noexcept {
  // This cycle's count frames wait for the next cycle; the ones held back from
  // the previous cycle follow this cycle's.
  const std::uint32_t id_a = board_.options().ids.counts_a_id();
  const std::uint32_t id_b = board_.options().ids.counts_b_id();
  std::array<can::CanFrame, 2> late{};
  const int late_n = held_n_;
  for (int i = 0; i < late_n; ++i) late[u(i)] = held_[u(i)];
  held_n_ = 0;
  if (hold) {
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
  return n;
}

int SimRig::apply_bus_faults(std::int64_t k, CycleFaults& f, SimBoard::Frames& out,
                             int n) noexcept {
  using K = SimFault::Kind;
  const bool lost = cycle_lost(k);
  if (lost || f.silent || f.dropped) {
    held_n_ = 0;  // whatever was held back is lost with the cycle
    f.applied |= (lost ? kRandomLossBit : 0U) | (f.silent ? fault_bit(K::kSilence) : 0U) |
                 (f.dropped ? fault_bit(K::kDrop) : 0U);
    return 0;
  }
  const std::uint32_t id_a = board_.options().ids.counts_a_id();
  const std::uint32_t id_b = board_.options().ids.counts_b_id();
  const bool partial = f.partial || cycle_partial(k);
  for (int i = n - 1; i >= 0; --i) {
    can::CanFrame& fr = out[u(i)];
    if (f.bad_seq && (fr.id == id_a || fr.id == id_b))
      fr.data[7] = static_cast<std::uint8_t>(fr.data[7] + 128);
    if (f.wrong_dlc && fr.id == id_b) fr.dlc = 6;
    if (partial && fr.id == id_b) erase_frame(out, n, i);
    if (f.duplicate && fr.id == id_a && n < static_cast<int>(out.size())) {
      for (int m = n; m > i; --m) out[u(m)] = out[u(m - 1)];  // out[i + 1] = the copy
      ++n;
    }
  }
  n = reorder(f.hold_counts, out, n);
  if (f.error_frame) {
    can::ErrorPayload e;
    e.classes = can::err_class::kProt | can::err_class::kBusError;
    e.protocol_type = can::err_prot::kBit;
    out[u(n++)] = can::encode_error(e);
  }
  f.applied |=
      (f.partial ? fault_bit(K::kPartial) : 0U) | (cycle_partial(k) ? kRandomPartialBit : 0U) |
      (f.duplicate ? fault_bit(K::kDuplicate) : 0U) |
      (f.hold_counts ? fault_bit(K::kReorder) : 0U) | (f.bad_seq ? fault_bit(K::kBadSeq) : 0U) |
      (f.wrong_dlc ? fault_bit(K::kWrongDlc) : 0U) |
      (f.error_frame ? fault_bit(K::kErrorFrame) : 0U) |
      (f.delay_ns > 0 ? fault_bit(K::kDelay) : 0U);
  return n;
}

int SimRig::step(std::int64_t k, SimBoard::Frames& out, std::int64_t start_mono_ns,
                 std::int64_t wall_offset_ns) noexcept {
  return step_at(k, sample_offset_ns(k), out, start_mono_ns, wall_offset_ns);
}

int SimRig::step_at(std::int64_t k, std::int64_t t_ns, SimBoard::Frames& out,
                    std::int64_t start_mono_ns, std::int64_t wall_offset_ns) noexcept {
  const double t_s = static_cast<double>(t_ns) * 1e-9;
  BoardCycle c = sample_board(t_s);
  CycleFaults f = active_faults(k, t_s);
  f.applied |= cycle_.applied;
  apply_counter_faults(k, t_s, f, c);
  const int made = board_.make_cycle(k, c, out);
  const int n = apply_bus_faults(k, f, out, made);
  const std::int64_t mono = start_mono_ns + t_ns + f.delay_ns;
  for (int i = 0; i < n; ++i) {
    out[u(i)].mono_ns = mono;
    out[u(i)].wall_ns = mono + wall_offset_ns;
  }
  cycle_.k = k;
  cycle_.t_s = t_s;
  cycle_.applied = f.applied;
  for (std::size_t b = 0; b < applied_.size(); ++b) {
    if ((f.applied & (1U << b)) != 0) ++applied_[b];
  }
  return n;
}

std::span<const SimFaultName> sim_fault_names() noexcept {
  using K = SimFault::Kind;
  namespace p = fault_param;
  static constexpr SimFaultName kNames[] = {
      {K::kCountOffset, "glitch", p::kJoint | p::kCounts},
      {K::kCountRamp, "lost_counts", p::kJoint | p::kCounts},
      {K::kExcursion, "excursion", p::kJoint | p::kCounts},
      {K::kStuck, "stuck", p::kJoint | p::kErrorBits},
      {K::kSilence, "silence"},
      {K::kDrop, "drop", p::kPercent},
      {K::kPartial, "partial"},
      {K::kDuplicate, "duplicate", p::kEvery},
      {K::kBoardError, "board_error", p::kErrorBits},
      {K::kReorder, "reorder"},
      {K::kBadSeq, "bad_seq", p::kEvery},
      {K::kWrongDlc, "wrong_dlc", p::kEvery},
      {K::kDelay, "delay", p::kDelay},
      {K::kErrorFrame, "error_frame", p::kEvery},
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

const SimFaultName* find_sim_fault(std::string_view name) noexcept {
  for (const SimFaultName& n : sim_fault_names()) {
    if (n.name == name) return &n;
  }
  return nullptr;
}

}  // namespace exodaq::drivers::sim
