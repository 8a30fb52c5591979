#pragma once
// Shared subscriber side of the exodaq tools (echo, status, and later tools):
// channel names with the rig prefix, recognising and decoding the four message
// types, flattening a message into named fields (CSV), naming flag bits, and a
// thin wrapper over lcm::LCM that hands decoded messages to a callback.
// Nothing here runs in the daemon; allocation is fine.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/status_t.hpp"

namespace lcm {
class LCM;
struct ReceiveBuffer;
}  // namespace lcm

namespace exodaq::tools::sub {

// Same default as the daemon: multicast, TTL 0, so nothing leaves the host.
inline constexpr const char* kDefaultUrl = "udpm://239.255.76.67:7667?ttl=0";

enum class Kind { kJointState, kPalmPose, kEncoderRaw, kStatus };
inline constexpr Kind kAllKinds[] = {Kind::kJointState, Kind::kPalmPose, Kind::kEncoderRaw,
                                     Kind::kStatus};

// "EXO_JOINT_STATE" etc., without prefix.
std::string_view base_channel(Kind k);
// "joint_state_t" etc.
std::string_view type_name(Kind k);
// prefix + base channel, e.g. "RIG2_" + "EXO_JOINT_STATE".
std::string channel_name(std::string_view prefix, Kind k);

// What a user typed for --channel: a short name ("joint_state", "palm", "raw",
// "status"), a base name ("EXO_PALM_POSE", case-insensitive) or a type name;
// nullopt if it is none of these (then it is taken as a literal channel name).
std::optional<Kind> parse_kind(std::string_view text);

// The type of an encoded message, from its 8-byte fingerprint; nullopt for a
// foreign type or a short buffer.
std::optional<Kind> kind_of_payload(const void* data, std::size_t size);

// LCM subscribes by regular expression (POSIX extended, anchored): escape a
// literal channel name so a prefix like "rig.2" matches only itself.
std::string regex_escape(std::string_view literal);

using Message = std::variant<joint_state_t, palm_pose_t, encoder_raw_t, status_t>;
Kind kind_of(const Message& m);
// Decodes `data` as `k`; nullopt if the bytes are not a complete message of
// that type (wrong fingerprint, truncated).
std::optional<Message> decode(Kind k, const void* data, std::size_t size);

// Common header of every message.
struct Stamp {
  int64_t utime = 0;
  int64_t mono_ns = 0;
  int64_t seq = 0;
  int64_t run_id = 0;
};
Stamp stamp_of(const Message& m);

// One message flattened to named scalar fields in declaration order; arrays
// become name_0 .. name_5. Values are exact: integers in decimal, doubles in
// the shortest text that reads back to the same double, booleans 0/1, strings
// as they are. The names for a kind do not depend on the values, so a CSV
// header is field_names(kind).
struct Field {
  std::string name;
  std::string value;
};
std::vector<Field> fields(const Message& m);
std::vector<std::string> field_names(Kind k);

// CSV (RFC 4180): quotes a value that holds a comma, quote or line break.
std::string csv_escape(std::string_view v);
std::string csv_line(const std::vector<std::string>& values);

// Exact shortest round-trip text of a double ("0.1", "1e-06", "nan", "inf").
std::string format_double(double v);

// Flag bits to names joined by '|': "STALE|HELD", "-" for none; unknown bits as
// 0x... so nothing is hidden.
std::string joint_flag_names(int32_t flags);
std::string sample_flag_names(int32_t flags);
std::string invalid_reason_names(int32_t reasons);
std::string_view state_name(int8_t state);
std::string_view bus_state_name(int8_t bus);
std::string_view homing_name(int8_t homing);

// A received and decoded message.
struct Received {
  std::string channel;
  Message msg;
  int64_t recv_utime = 0;  // local wall clock at receipt, us
};

// lcm::LCM with raw subscriptions that decode by kind. Not thread-safe; drive
// it from one thread with handle().
class Subscriber {
 public:
  using Handler = std::function<void(const Received&)>;
  // Throws std::runtime_error naming the URL if LCM cannot be set up (for
  // udpm: no multicast route, bad URL).
  explicit Subscriber(const std::string& url);
  ~Subscriber();
  Subscriber(const Subscriber&) = delete;
  Subscriber& operator=(const Subscriber&) = delete;

  // Subscribes to exactly `channel` (escaped). If `kind` is nullopt the type
  // is recognised from the fingerprint. Messages that do not decode are
  // counted in undecodable() and not passed on.
  void subscribe(const std::string& channel, std::optional<Kind> kind, Handler handler);

  // Waits up to timeout_ms for traffic and dispatches it. >0: handled
  // messages, 0: timeout, <0: error.
  int handle(int timeout_ms);
  // The descriptor that becomes readable when handle() has traffic to
  // dispatch, for callers that poll() several sources in one thread.
  int fileno();

  int64_t undecodable() const { return undecodable_; }

 private:
  struct Sub;
  static void on_raw(const lcm::ReceiveBuffer* rbuf, const std::string& channel, Sub* sub);

  std::unique_ptr<lcm::LCM> lcm_;
  std::list<Sub> subs_;
  int64_t undecodable_ = 0;
};

// Wall clock now, us since the Unix epoch.
int64_t now_utime();
// Monotonic clock now, ns.
int64_t now_mono_ns();

}  // namespace exodaq::tools::sub
