#include "exodaq/messages/fields.hpp"

#include <charconv>
#include <cmath>
#include <cstdint>

namespace exodaq::msg {

namespace {

// Flattening: one overload per field type.
class Flattener {
 public:
  explicit Flattener(std::vector<Field>& out) : out_(out) {}

  void add(std::string_view name, std::string value) {
    out_.push_back(Field{std::string(name), std::move(value)});
  }
  void operator()(std::string_view name, std::int64_t v) { add(name, std::to_string(v)); }
  void operator()(std::string_view name, std::int32_t v) { add(name, std::to_string(v)); }
  void operator()(std::string_view name, std::int16_t v) { add(name, std::to_string(v)); }
  // std::int8_t is both LCM's int8_t and boolean; both print as a number.
  void operator()(std::string_view name, std::int8_t v) { add(name, std::to_string(int{v})); }
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

}  // namespace

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

}  // namespace exodaq::msg
