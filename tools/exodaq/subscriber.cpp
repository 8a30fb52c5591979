#include "subscriber.hpp"

#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <type_traits>
#include <utility>

namespace exodaq::tools::sub {

namespace {

struct KindInfo {
  Kind kind;
  std::string_view base;
  std::string_view type;
  std::string_view short_name;
};

constexpr KindInfo kInfo[] = {
    {Kind::kJointState, "EXO_JOINT_STATE", "joint_state_t", "joint_state"},
    {Kind::kPalmPose, "EXO_PALM_POSE", "palm_pose_t", "palm_pose"},
    {Kind::kEncoderRaw, "EXO_ENCODER_RAW", "encoder_raw_t", "encoder_raw"},
    {Kind::kStatus, "EXO_STATUS", "status_t", "status"},
};

const KindInfo& info(Kind k) {
  for (const auto& i : kInfo) {
    if (i.kind == k) return i;
  }
  return kInfo[0];
}

std::string upper(std::string_view s) {
  std::string out(s);
  for (auto& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

template <typename T>
uint64_t fingerprint() {
  return static_cast<uint64_t>(T::getHash());
}

// Flattening: one overload per field type.
class Flattener {
 public:
  explicit Flattener(std::vector<Field>& out) : out_(out) {}

  void add(std::string_view name, std::string value) {
    out_.push_back(Field{std::string(name), std::move(value)});
  }
  void operator()(std::string_view name, int64_t v) { add(name, std::to_string(v)); }
  void operator()(std::string_view name, int32_t v) { add(name, std::to_string(v)); }
  void operator()(std::string_view name, int16_t v) { add(name, std::to_string(v)); }
  // int8_t is both LCM's int8_t and boolean; both print as a number.
  void operator()(std::string_view name, int8_t v) { add(name, std::to_string(int{v})); }
  void operator()(std::string_view name, double v) { add(name, format_double(v)); }
  void operator()(std::string_view name, const std::string& v) { add(name, v); }
  template <typename T, std::size_t N>
  void operator()(std::string_view name, const T (&a)[N]) {
    for (std::size_t i = 0; i < N; ++i) (*this)(std::string(name) + "_" + std::to_string(i), a[i]);
  }

 private:
  std::vector<Field>& out_;
};

#define EXODAQ_F(field) f(#field, m.field)

void flatten(const joint_state_t& m, Flattener& f) {
  EXODAQ_F(utime);
  EXODAQ_F(mono_ns);
  EXODAQ_F(seq);
  EXODAQ_F(run_id);
  EXODAQ_F(name);
  EXODAQ_F(position);
  EXODAQ_F(velocity);
  EXODAQ_F(raw_count);
  EXODAQ_F(homed);
  EXODAQ_F(flags);
  EXODAQ_F(sample_flags);
}

void flatten(const palm_pose_t& m, Flattener& f) {
  EXODAQ_F(utime);
  EXODAQ_F(mono_ns);
  EXODAQ_F(seq);
  EXODAQ_F(run_id);
  EXODAQ_F(valid);
  EXODAQ_F(invalid_reason);
  EXODAQ_F(position);
  EXODAQ_F(orientation);
  EXODAQ_F(elbow);
  EXODAQ_F(shoulder_manipulability);
  EXODAQ_F(shoulder_manipulability_raw);
  EXODAQ_F(near_singular);
}

void flatten(const encoder_raw_t& m, Flattener& f) {
  EXODAQ_F(utime);
  EXODAQ_F(mono_ns);
  EXODAQ_F(seq);
  EXODAQ_F(run_id);
  EXODAQ_F(present);
  EXODAQ_F(board_seq);
  EXODAQ_F(count16);
  EXODAQ_F(index_count16);
  EXODAQ_F(index_latched);
  EXODAQ_F(index_count_valid);
  EXODAQ_F(board_state);
  EXODAQ_F(board_errors);
  EXODAQ_F(source_flags);
  EXODAQ_F(wall_ns);
}

void flatten(const status_t& m, Flattener& f) {
  EXODAQ_F(utime);
  EXODAQ_F(mono_ns);
  EXODAQ_F(seq);
  EXODAQ_F(run_id);
  EXODAQ_F(rig);
  EXODAQ_F(state);
  EXODAQ_F(message);
  EXODAQ_F(window_cycles);
  EXODAQ_F(period_p50_us);
  EXODAQ_F(period_p99_us);
  EXODAQ_F(period_max_us);
  EXODAQ_F(lateness_p50_us);
  EXODAQ_F(lateness_p99_us);
  EXODAQ_F(lateness_max_us);
  EXODAQ_F(work_p50_us);
  EXODAQ_F(work_p99_us);
  EXODAQ_F(work_max_us);
  EXODAQ_F(overruns);
  EXODAQ_F(cycles);
  EXODAQ_F(publish_failures);
  EXODAQ_F(source);
  EXODAQ_F(frames);
  EXODAQ_F(bad_frames);
  EXODAQ_F(missing_samples);
  EXODAQ_F(seq_gaps);
  EXODAQ_F(duplicates);
  EXODAQ_F(out_of_order);
  EXODAQ_F(bus_errors);
  EXODAQ_F(rx_overflows);
  EXODAQ_F(bus_state);
  EXODAQ_F(board_errors);
  EXODAQ_F(clock_synchronised);
  EXODAQ_F(clock_est_error_us);
  EXODAQ_F(clock_max_error_us);
  EXODAQ_F(clock_offset_us);
  EXODAQ_F(utime_correction_us);
  EXODAQ_F(clock_steps);
  EXODAQ_F(joint_name);
  EXODAQ_F(homing);
  EXODAQ_F(joint_flags);
  EXODAQ_F(glitches);
  EXODAQ_F(lost_count_events);
  EXODAQ_F(stale_events);
  EXODAQ_F(out_of_range_events);
}

#undef EXODAQ_F

struct BitName {
  int32_t bit;
  std::string_view name;
};

std::string bit_names(int32_t flags, std::initializer_list<BitName> names) {
  if (flags == 0) return "-";
  std::string out;
  auto rest = static_cast<uint32_t>(flags);
  for (const auto& n : names) {
    if (rest & static_cast<uint32_t>(n.bit)) {
      if (!out.empty()) out += '|';
      out += n.name;
      rest &= ~static_cast<uint32_t>(n.bit);
    }
  }
  if (rest != 0) {
    char buf[16];
    std::snprintf(buf, sizeof buf, "0x%x", rest);
    if (!out.empty()) out += '|';
    out += buf;
  }
  return out;
}

}  // namespace

std::string_view base_channel(Kind k) {
  return info(k).base;
}
std::string_view type_name(Kind k) {
  return info(k).type;
}

std::string channel_name(std::string_view prefix, Kind k) {
  return std::string(prefix) + std::string(base_channel(k));
}

std::optional<Kind> parse_kind(std::string_view text) {
  const std::string u = upper(text);
  for (const auto& i : kInfo) {
    if (u == upper(i.base) || u == upper(i.type) || u == upper(i.short_name)) return i.kind;
  }
  if (u == "JOINT" || u == "JOINTS") return Kind::kJointState;
  if (u == "PALM" || u == "POSE") return Kind::kPalmPose;
  if (u == "RAW" || u == "ENCODER") return Kind::kEncoderRaw;
  return std::nullopt;
}

std::optional<Kind> kind_of_payload(const void* data, std::size_t size) {
  if (size < 8) return std::nullopt;
  const auto* b = static_cast<const unsigned char*>(data);
  uint64_t fp = 0;
  for (int i = 0; i < 8; ++i) fp = (fp << 8) | b[i];
  if (fp == fingerprint<joint_state_t>()) return Kind::kJointState;
  if (fp == fingerprint<palm_pose_t>()) return Kind::kPalmPose;
  if (fp == fingerprint<encoder_raw_t>()) return Kind::kEncoderRaw;
  if (fp == fingerprint<status_t>()) return Kind::kStatus;
  return std::nullopt;
}

std::string regex_escape(std::string_view literal) {
  std::string out;
  for (char c : literal) {
    if (std::strchr(".[]{}()\\*+?^$|", c) != nullptr) out += '\\';
    out += c;
  }
  return out;
}

Kind kind_of(const Message& m) {
  return std::visit(
      [](const auto& v) {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, joint_state_t>) return Kind::kJointState;
        if constexpr (std::is_same_v<T, palm_pose_t>) return Kind::kPalmPose;
        if constexpr (std::is_same_v<T, encoder_raw_t>) return Kind::kEncoderRaw;
        if constexpr (std::is_same_v<T, status_t>) return Kind::kStatus;
      },
      m);
}

namespace {
template <typename T>
std::optional<Message> decode_as(const void* data, std::size_t size) {
  if (size > static_cast<std::size_t>(INT32_MAX)) return std::nullopt;
  T msg;
  const int n = msg.decode(data, 0, static_cast<int>(size));
  if (n < 0 || static_cast<std::size_t>(n) != size) return std::nullopt;
  return Message{std::move(msg)};
}
}  // namespace

std::optional<Message> decode(Kind k, const void* data, std::size_t size) {
  switch (k) {
    case Kind::kJointState:
      return decode_as<joint_state_t>(data, size);
    case Kind::kPalmPose:
      return decode_as<palm_pose_t>(data, size);
    case Kind::kEncoderRaw:
      return decode_as<encoder_raw_t>(data, size);
    case Kind::kStatus:
      return decode_as<status_t>(data, size);
  }
  return std::nullopt;
}

Stamp stamp_of(const Message& m) {
  return std::visit([](const auto& v) { return Stamp{v.utime, v.mono_ns, v.seq, v.run_id}; }, m);
}

std::vector<Field> fields(const Message& m) {
  std::vector<Field> out;
  Flattener f(out);
  std::visit([&f](const auto& v) { flatten(v, f); }, m);
  return out;
}

std::vector<std::string> field_names(Kind k) {
  Message m;
  switch (k) {
    case Kind::kJointState:
      m = joint_state_t{};
      break;
    case Kind::kPalmPose:
      m = palm_pose_t{};
      break;
    case Kind::kEncoderRaw:
      m = encoder_raw_t{};
      break;
    case Kind::kStatus:
      m = status_t{};
      break;
  }
  std::vector<std::string> names;
  for (auto& f : fields(m)) names.push_back(std::move(f.name));
  return names;
}

std::string csv_escape(std::string_view v) {
  if (v.find_first_of(",\"\r\n") == std::string_view::npos) return std::string(v);
  std::string out = "\"";
  for (char c : v) {
    if (c == '"') out += '"';
    out += c;
  }
  out += '"';
  return out;
}

std::string csv_line(const std::vector<std::string>& values) {
  std::string out;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i) out += ',';
    out += csv_escape(values[i]);
  }
  return out;
}

std::string format_double(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string joint_flag_names(int32_t flags) {
  return bit_names(flags, {{joint_state_t::JOINT_UNHOMED, "UNHOMED"},
                           {joint_state_t::JOINT_STALE, "STALE"},
                           {joint_state_t::JOINT_GLITCH, "GLITCH"},
                           {joint_state_t::JOINT_OUT_OF_RANGE, "OUT_OF_RANGE"},
                           {joint_state_t::JOINT_LOST_COUNTS, "LOST_COUNTS"},
                           {joint_state_t::JOINT_HOMING_REJECTED, "HOMING_REJECTED"},
                           {joint_state_t::JOINT_HELD, "HELD"},
                           {joint_state_t::JOINT_BOARD_ERROR, "BOARD_ERROR"}});
}

std::string sample_flag_names(int32_t flags) {
  return bit_names(flags, {{joint_state_t::SAMPLE_MISSING, "MISSING"},
                           {joint_state_t::SAMPLE_SEQ_GAP, "SEQ_GAP"},
                           {joint_state_t::SAMPLE_DUPLICATE, "DUPLICATE"},
                           {joint_state_t::SAMPLE_OUT_OF_ORDER, "OUT_OF_ORDER"},
                           {joint_state_t::SAMPLE_BOARD_ERROR, "BOARD_ERROR"},
                           {joint_state_t::SAMPLE_BUS_ERROR, "BUS_ERROR"},
                           {joint_state_t::SAMPLE_CLOCK_STEP, "CLOCK_STEP"},
                           {joint_state_t::SAMPLE_CLOCK_UNSYNC, "CLOCK_UNSYNC"},
                           {joint_state_t::SAMPLE_LATE, "LATE"},
                           {joint_state_t::SAMPLE_PARTIAL, "PARTIAL"},
                           {joint_state_t::SAMPLE_REPLAY, "REPLAY"}});
}

std::string invalid_reason_names(int32_t reasons) {
  return bit_names(reasons, {{palm_pose_t::INVALID_UNHOMED, "UNHOMED"},
                             {palm_pose_t::INVALID_JOINT_FAULT, "JOINT_FAULT"},
                             {palm_pose_t::INVALID_SAMPLE, "SAMPLE"},
                             {palm_pose_t::INVALID_SOURCE, "SOURCE"},
                             {palm_pose_t::INVALID_CLOCK, "CLOCK"}});
}

std::string_view state_name(int8_t state) {
  switch (state) {
    case status_t::STATE_STARTING:
      return "STARTING";
    case status_t::STATE_HOMING:
      return "HOMING";
    case status_t::STATE_RUNNING:
      return "RUNNING";
    case status_t::STATE_DEGRADED:
      return "DEGRADED";
    case status_t::STATE_FAULT:
      return "FAULT";
    case status_t::STATE_STOPPING:
      return "STOPPING";
    default:
      return "UNKNOWN_STATE";
  }
}

std::string_view bus_state_name(int8_t bus) {
  switch (bus) {
    case status_t::BUS_UNKNOWN:
      return "UNKNOWN";
    case status_t::BUS_ACTIVE:
      return "ACTIVE";
    case status_t::BUS_WARNING:
      return "WARNING";
    case status_t::BUS_PASSIVE:
      return "PASSIVE";
    case status_t::BUS_OFF:
      return "OFF";
    case status_t::BUS_DOWN:
      return "DOWN";
    default:
      return "?";
  }
}

std::string_view homing_name(int8_t homing) {
  switch (homing) {
    case status_t::HOMING_UNHOMED:
      return "UNHOMED";
    case status_t::HOMING_HOMED:
      return "HOMED";
    case status_t::HOMING_REJECTED:
      return "REJECTED";
    default:
      return "?";
  }
}

struct Subscriber::Sub {
  Subscriber* owner = nullptr;
  std::optional<Kind> kind;
  Handler handler;
};

Subscriber::Subscriber(const std::string& url) : lcm_(std::make_unique<lcm::LCM>(url)) {
  if (!lcm_->good()) {
    throw std::runtime_error("cannot open LCM at '" + url +
                             "' (bad URL, or no multicast route: see docs/messages.md)");
  }
}

Subscriber::~Subscriber() = default;

void Subscriber::subscribe(const std::string& channel, std::optional<Kind> kind, Handler handler) {
  subs_.push_back(Sub{this, kind, std::move(handler)});
  lcm_->subscribeFunction(regex_escape(channel), &Subscriber::on_raw, &subs_.back());
}

void Subscriber::on_raw(const lcm::ReceiveBuffer* rbuf, const std::string& channel, Sub* sub) {
  const auto k = sub->kind ? sub->kind : kind_of_payload(rbuf->data, rbuf->data_size);
  std::optional<Message> msg;
  if (k) msg = decode(*k, rbuf->data, rbuf->data_size);
  if (!msg) {
    ++sub->owner->undecodable_;
    return;
  }
  sub->handler(Received{channel, std::move(*msg), rbuf->recv_utime});
}

int Subscriber::handle(int timeout_ms) {
  return lcm_->handleTimeout(timeout_ms);
}

int Subscriber::fileno() {
  return lcm_->getFileno();
}

int64_t now_utime() {
  using namespace std::chrono;
  return duration_cast<microseconds>(system_clock::now().time_since_epoch()).count();
}

int64_t now_mono_ns() {
  using namespace std::chrono;
  return duration_cast<nanoseconds>(steady_clock::now().time_since_epoch()).count();
}

}  // namespace exodaq::tools::sub
