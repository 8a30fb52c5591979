#pragma once
// Every setting of the service configuration, declared once: its field, key,
// type, default, rule (range or choices, and the words an error uses), unit,
// how a reload applies it, and one line of documentation. The settings
// structs (service_settings.hpp), the parser and --print-config
// (service_config.cpp), the reload classes (setting_classes.cpp) and the
// table in docs/operations.md (settings_table(), checked by a test) are all
// produced from these lists. Adding a setting is one row here and the code
// that uses the value.
//
// A row: X(type, field, "key", default, unit, rule, reload, "doc").
// The key is the YAML key inside its section; the error for a value outside
// the rule is "<section>.<key> <rule text>" (file:line first).
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>

namespace exodaq::settings {

// The unit of a key as written; `scale` converts it to the field's unit
// (clock.step_threshold_ms is kept in ns).
struct Unit {
  std::string_view name;
  double scale = 1.0;
};
namespace unit {
inline constexpr Unit kNone{};
inline constexpr Unit kHz{"Hz"};
inline constexpr Unit kMs{"ms"};
inline constexpr Unit kMsAsNs{"ms", 1e6};
inline constexpr Unit kUs{"us"};
inline constexpr Unit kDeg{"deg"};
inline constexpr Unit kRadPerS{"rad/s"};
inline constexpr Unit kPpm{"ppm"};
inline constexpr Unit kCounts{"counts"};
inline constexpr Unit kSamples{"samples"};
}  // namespace unit

// What a value must be. Numbers: within [lo, hi] (an open end excludes it) or
// one of `choices` ("1|2|4"); text: one of `choices`, or a length within
// [lo, hi]. `text` completes the error after the key ("must be positive");
// where the parser's code checks more than the bounds (a URL's form, a
// status rate above the loop's), its error uses these words.
struct Rule {
  std::string_view text;
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;
  bool hi_open = false;
  std::string_view choices;
  bool required = false;
};
namespace rule {
constexpr Rule any() {
  return {};
}
constexpr Rule within(double lo, bool lo_open, double hi, bool hi_open, std::string_view text) {
  Rule r;
  r.text = text;
  r.lo = lo;
  r.lo_open = lo_open;
  r.hi = hi;
  r.hi_open = hi_open;
  return r;
}
constexpr Rule between(double lo, double hi, std::string_view text) {
  return within(lo, false, hi, false, text);
}
constexpr Rule above(double lo, std::string_view text) {
  return within(lo, true, std::numeric_limits<double>::infinity(), false, text);
}
constexpr Rule at_least(double lo, std::string_view text) {
  return between(lo, std::numeric_limits<double>::infinity(), text);
}
constexpr Rule one_of(std::string_view choices, std::string_view text = {}) {
  Rule r;
  r.text = text;
  r.choices = choices;
  return r;
}
// A rule the parser's code checks in full (in these words).
constexpr Rule checked(std::string_view text) {
  Rule r;
  r.text = text;
  return r;
}
constexpr Rule required(Rule r) {
  r.required = true;
  return r;
}
}  // namespace rule

// How a reload (SIGHUP) applies a setting (setting_classes.hpp).
enum class Reload : std::uint8_t {
  kLive,        // at the next cycle boundary
  kNewSegment,  // live, and the samples after it start a new segment (positions may jump)
  kRestart,     // read at start-up only
};

// How sample time treats the wall clock (docs/time.md); the order of
// clock.require_sync's choices.
enum class RequireSync : std::uint8_t {
  kIgnore,  // clock health reported only
  kMark,    // samples carry SAMPLE_CLOCK_UNSYNC while unsynchronised
  kHold,    // as kMark, and the service stays degraded (palm invalid) until synchronised
};

// The longest velocity fit a joint tracker holds (encoders.velocity_window).
inline constexpr int kMaxVelocityWindow = 64;
static_assert(kMaxVelocityWindow == 64, "encoders.velocity_window's rule says 'between 2 and 64'");

// Top level.
#define EXODAQ_TOP_SETTINGS(X)                                                            \
  X(std::string, rig, "rig", "rig", unit::kNone,                                          \
    rule::required(rule::between(1, 63, "must be 1 to 63 characters")), Reload::kRestart, \
    "the rig's name, carried in every message")

#define EXODAQ_LOOP_SETTINGS(X)                                                                    \
  X(double, rate_hz, "rate_hz", 1000.0, unit::kHz,                                                 \
    rule::between(10, 10'000, "must be between 10 and 10000 Hz"), Reload::kRestart,                \
    "cycles per second of the acquisition loop")                                                   \
  X(int, cpu, "cpu", -1, unit::kNone, rule::between(-1, 1023, "must be -1 (any) or a CPU number"), \
    Reload::kRestart, "the CPU the loop thread is pinned to (-1: no pinning)")                     \
  X(int, priority, "priority", 0, unit::kNone,                                                     \
    rule::between(0, 99, "must be 0 (SCHED_OTHER) or a SCHED_FIFO priority 1..99"),                \
    Reload::kRestart, "SCHED_FIFO priority of the loop thread (0: SCHED_OTHER)")                   \
  X(bool, lock_memory, "lock_memory", false, unit::kNone, rule::any(), Reload::kRestart,           \
    "lock the process's memory (mlockall) before the loop starts")                                 \
  X(std::int64_t, fault_after_ms, "fault_after_ms", 500, unit::kMs,                                \
    rule::at_least(1, "must be positive"), Reload::kRestart,                                       \
    "no sample for this long: state fault")                                                        \
  X(double, status_rate_hz, "status_rate_hz", 10.0, unit::kHz,                                     \
    rule::above(0, "must be positive and at most loop.rate_hz"), Reload::kRestart,                 \
    "status messages per second")

#define EXODAQ_ENCODER_SETTINGS(X)                                                                \
  X(int, cycles_per_rev, "cycles_per_rev", 2500, unit::kNone,                                     \
    rule::between(1, 1'000'000, "must be between 1 and 1000000"), Reload::kNewSegment,            \
    "cycles per revolution of the encoder disc")                                                  \
  X(int, decoding, "decoding", 4, unit::kNone,                                                    \
    rule::one_of("1|2|4", "must be 1, 2 or 4 (quadrature decoding factor)"), Reload::kNewSegment, \
    "quadrature decoding factor: counts per cycle")                                               \
  X(double, stale_ms, "stale_ms", 20.0, unit::kMs, rule::above(0, "must be positive"),            \
    Reload::kLive, "a joint without a fresh count for longer is STALE")                           \
  X(std::int64_t, index_tolerance_counts, "index_tolerance_counts", 2, unit::kCounts,             \
    rule::at_least(0, "must be >= 0"), Reload::kLive,                                             \
    "an index this far off a whole revolution of its reference is LOST_COUNTS")                   \
  X(double, limit_margin_deg, "limit_margin_deg", 2.0, unit::kDeg,                                \
    rule::at_least(0, "must be >= 0"), Reload::kLive,                                             \
    "an angle this far beyond the model's limits is OUT_OF_RANGE")                                \
  X(double, speed_margin, "speed_margin", 1.5, unit::kNone, rule::at_least(1, "must be >= 1"),    \
    Reload::kLive, "glitch bound = a joint's max_speed_rad_s x this")                             \
  X(int, velocity_window, "velocity_window", 21, unit::kSamples,                                  \
    rule::between(2, kMaxVelocityWindow, "must be between 2 and 64"), Reload::kLive,              \
    "samples in the velocity fit")                                                                \
  X(double, fault_hold_ms, "fault_hold_ms", 100.0, unit::kMs, rule::at_least(0, "must be >= 0"),  \
    Reload::kLive, "how long LOST_COUNTS stays after a correction")

// Each entry of encoders.joints (six, one per joint); errors name the key alone.
#define EXODAQ_JOINT_SETTINGS(X)                                                                  \
  X(int, channel, "channel", 0, unit::kNone, rule::required(rule::between(0, 5, "must be 0..5")), \
    Reload::kNewSegment, "the board input of this joint (each input once)")                       \
  X(int, direction, "direction", 1, unit::kNone, rule::one_of("1|-1", "must be 1 or -1"),         \
    Reload::kNewSegment, "+1 when the count rises as the joint's angle rises, else -1")           \
  X(double, gear_ratio, "gear_ratio", 1.0, unit::kNone,                                           \
    rule::within(0, true, 100, false,                                                             \
                 "must be in (0, 100] encoder revolutions per joint revolution"),                 \
    Reload::kNewSegment, "encoder revolutions per joint revolution")                              \
  X(double, max_speed_rad_s, "max_speed_rad_s", 0.0, unit::kRadPerS,                              \
    rule::required(rule::above(0, "must be positive")), Reload::kLive,                            \
    "the joint's fastest plausible speed (at most its whole range in 50 ms)")

// ServiceConfig's own fields, under kinematics:.
#define EXODAQ_KINEMATICS_SETTINGS(X)                                          \
  X(double, singularity_threshold, "singularity_threshold", 0.05, unit::kNone, \
    rule::within(0, false, 1, true, "must be in [0, 1)"), Reload::kLive,       \
    "near_singular below this normalised shoulder manipulability")

#define EXODAQ_LCM_SETTINGS(X)                                                          \
  X(std::string, url, "url", "udpm://239.255.76.67:7667?ttl=0", unit::kNone,            \
    rule::checked("must be an LCM URL (udpm://group:port?ttl=N)"), Reload::kRestart,    \
    "where messages go: udpm:// with a multicast group, file:// or memq://")            \
  X(std::string, prefix, "prefix", "", unit::kNone,                                     \
    rule::checked("may hold letters, digits and _ - . / only"), Reload::kRestart,       \
    "prepended to every channel name (several rigs on one network)")                    \
  X(bool, publish_raw, "publish_raw", true, unit::kNone, rule::any(), Reload::kRestart, \
    "publish the raw counts (EXO_ENCODER_RAW) too")

#define EXODAQ_CLOCK_SETTINGS(X)                                                                  \
  X(RequireSync, require_sync, "require_sync", RequireSync::kMark, unit::kNone,                   \
    rule::one_of("ignore|mark|hold"), Reload::kLive,                                              \
    "what an unsynchronised wall clock does to the samples (docs/time.md)")                       \
  X(double, max_est_error_us, "max_est_error_us", 5'000.0, unit::kUs, rule::any(), Reload::kLive, \
    "synchronised needs the kernel's esterror at most this")                                      \
  X(double, max_max_error_us, "max_max_error_us", 100'000.0, unit::kUs, rule::any(),              \
    Reload::kLive, "... and its maxerror at most this")                                           \
  X(std::int64_t, step_threshold_ns, "step_threshold_ms", 2'000'000, unit::kMsAsNs,               \
    rule::above(0, "must be positive"), Reload::kLive,                                            \
    "a clock offset change larger than this is a step")                                           \
  X(double, slew_ppm, "slew_ppm", 1'000.0, unit::kPpm,                                            \
    rule::within(0, true, 1e5, false, "must be in (0, 100000]"), Reload::kLive,                   \
    "ordinary tracking rate of sample time (NTP slews at most 500 ppm)")                          \
  X(double, step_slew_ppm, "step_slew_ppm", 100'000.0, unit::kPpm,                                \
    rule::within(0, true, 5e5, false, "must be in (0, 500000]"), Reload::kLive,                   \
    "how fast a clock step is absorbed")

#define EXODAQ_LOGGING_SETTINGS(X)                                                       \
  X(std::string, level, "level", "info", unit::kNone,                                    \
    rule::one_of("trace|debug|info|warn|error|critical|off"), Reload::kLive,             \
    "log level (--log-level and SPDLOG_LEVEL override it)")                              \
  X(std::string, sink, "sink", "auto", unit::kNone, rule::one_of("auto|stderr|journal"), \
    Reload::kRestart, "where the log goes (auto: the journal under systemd)")

// A field of a settings struct, from its row.
#define EXODAQ_SETTING_FIELD(type, field, key, def, unit, rule, reload, doc) type field = def;

}  // namespace exodaq::settings
