#include "view_scene.hpp"

#include <cstdio>
#include <stdexcept>
#include <utility>

#include "clock_text.hpp"
#include "exodaq/common/clock_now.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/flag_names.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq/messages/subscriber.hpp"
#include "exodaq/version.hpp"
#include "view_json.hpp"

namespace exodaq::tools::view {

namespace {

constexpr int32_t kUnhomedBits = joint_state_t::JOINT_UNHOMED;
constexpr int32_t kHeldBits = joint_state_t::JOINT_HELD;

void write_vec(JsonWriter& j, const Eigen::Vector3d& v) {
  j.begin_array().value(v.x()).value(v.y()).value(v.z()).end_array();
}

template <typename T, std::size_t N>
void write_array(JsonWriter& j, const std::array<T, N>& a) {
  j.begin_array();
  for (const auto& v : a) j.value(v);
  j.end_array();
}

double seconds(int64_t ns) {
  return static_cast<double>(ns) * 1e-9;
}

}  // namespace

std::string_view stream_state_name(StreamState s) {
  switch (s) {
    case StreamState::kWaiting:
      return "waiting";
    case StreamState::kLive:
      return "live";
    case StreamState::kNoData:
      return "no-data";
    case StreamState::kStopped:
      return "stopped";
  }
  return "?";
}

std::string_view joint_class(bool homed, int32_t flags) {
  if ((flags & ~(kUnhomedBits | kHeldBits)) != 0) return "fault";
  if (!homed || (flags & kUnhomedBits) != 0) return "unhomed";
  if ((flags & kHeldBits) != 0) return "held";
  return "ok";
}

ViewScene::ViewScene(ViewModel model, SceneOptions options)
    : model_(std::move(model)), options_(std::move(options)) {
  const int n = model_.chain.joint_count();
  if (n != kViewJoints) {
    throw std::invalid_argument("model '" + model_.name + "' has " + std::to_string(n) +
                                " joints; the joint_state_t messages carry " +
                                std::to_string(kViewJoints));
  }
  // The page's scale: the length of the chain of frame origins (constant for
  // DH chains, whose every origin lies on the next joint's axis).
  const kinematics::JointVector q = kinematics::JointVector::Zero(n);
  for (int i = 1; i <= n + 1; ++i) {
    reach_m_ +=
        (model_.chain.frame(q, i).translation() - model_.chain.frame(q, i - 1).translation())
            .norm();
  }
  model_.joint_names.resize(kViewJoints);
}

void ViewScene::on_joint_state(const joint_state_t& m, int64_t now_ns) {
  if (joints_ && joints_->run_id != m.run_id) {
    trail_.clear();  // a new daemon run: its trail starts afresh
    meter_.clear();
  }
  Joints j;
  j.seq = m.seq;
  j.run_id = m.run_id;
  j.utime = m.utime;
  j.mono_ns = m.mono_ns;
  for (int i = 0; i < kViewJoints; ++i) {
    j.q[static_cast<std::size_t>(i)] = m.position[i];
    j.qd[static_cast<std::size_t>(i)] = m.velocity[i];
    j.homed[static_cast<std::size_t>(i)] = m.homed[i] != 0;
    j.flags[static_cast<std::size_t>(i)] = m.flags[i];
    if (model_.joint_names[static_cast<std::size_t>(i)] != m.name[i]) {
      model_.joint_names[static_cast<std::size_t>(i)] = m.name[i];
    }
  }
  j.sample_flags = m.sample_flags;
  joints_ = j;
  joint_local_ns_ = now_ns;
  ++joint_messages_;
  ++since_frame_;
  joint_dirty_ = true;
  meter_.add(messages::Stamp{m.utime, m.mono_ns, m.seq, m.run_id}, now_ns);
}

void ViewScene::on_palm_pose(const palm_pose_t& m, int64_t /*now_ns*/) {
  Palm p;
  p.seq = m.seq;
  p.run_id = m.run_id;
  p.valid = m.valid != 0;
  p.invalid_reason = m.invalid_reason;
  for (std::size_t i = 0; i < 3; ++i) {
    p.position[i] = m.position[i];
    p.elbow[i] = m.elbow[i];
  }
  p.manipulability = m.shoulder_manipulability;
  p.near_singular = m.near_singular != 0;
  palm_ = p;
}

void ViewScene::on_status(const status_t& m, int64_t now_ns) {
  status_ = m;
  status_local_ns_ = now_ns;
  status_dirty_ = true;
}

void ViewScene::on_source_status(const source_status_t& m) {
  source_status_ = m;
  status_dirty_ = status_.has_value();
}

StreamState ViewScene::stream_state(int64_t now_ns) const {
  // The service said it stops, and no joint state came after that.
  const bool stopping = status_ && status_->state == status_t::STATE_STOPPING &&
                        (!joints_ || status_local_ns_ >= joint_local_ns_);
  if (stopping) return StreamState::kStopped;
  if (!joints_) return StreamState::kWaiting;
  if (seconds(now_ns - joint_local_ns_) > options_.silence_s) return StreamState::kNoData;
  return StreamState::kLive;
}

std::string ViewScene::stream_json(int64_t now_ns) const {
  const StreamState s = stream_state(now_ns);
  const std::string joint_channel =
      messages::channel_name(options_.prefix, messages::Kind::kJointState);
  std::string reason;
  char buf[160];
  switch (s) {
    case StreamState::kWaiting:
      reason = "no message on " + joint_channel + " yet";
      break;
    case StreamState::kLive:
      break;
    case StreamState::kNoData:
      std::snprintf(buf, sizeof buf, "nothing on %s for %.1f s", joint_channel.c_str(),
                    seconds(now_ns - joint_local_ns_));
      reason = buf;
      break;
    case StreamState::kStopped:
      reason = "the service stopped (its last status said STOPPING)";
      break;
  }
  JsonWriter j;
  j.begin_object().field("state", stream_state_name(s)).field("reason", reason);
  j.key("age_s");
  joints_ ? j.value(seconds(now_ns - joint_local_ns_)) : j.null();
  j.key("status_age_s");
  status_ ? j.value(seconds(now_ns - status_local_ns_)) : j.null();
  j.key("run_id");
  joints_ ? j.value(messages::run_id_text(joints_->run_id)) : j.null();
  j.key("rate_hz");
  const auto rate = meter_.rate_hz();
  rate ? j.value(*rate) : j.null();
  j.key("received");
  const auto recv = meter_.received_fraction();
  recv ? j.value(*recv) : j.null();
  j.field("messages", joint_messages_).field("frames", frames_built_);
  j.end_object();
  return j.str();
}

std::string ViewScene::frame_json() {
  const Joints& js = *joints_;
  const int n = model_.chain.joint_count();
  kinematics::JointVector q(n);
  for (int i = 0; i < n; ++i) q[i] = js.q[static_cast<std::size_t>(i)];
  frames_.resize(static_cast<std::size_t>(n) + 2);
  for (int i = 0; i <= n + 1; ++i) {
    frames_[static_cast<std::size_t>(i)] = model_.chain.frame(q, i).translation();
  }
  ++frames_built_;
  const Eigen::Vector3d& palm = frames_.back();
  const int elbow = std::clamp(model_.elbow_frame, 0, n + 1);
  const Eigen::Vector3d& elbow_fk = frames_[static_cast<std::size_t>(elbow)];

  trail_.push_back(TrailPoint{seconds(js.mono_ns), palm});
  while (!trail_.empty() && trail_.front().t < seconds(js.mono_ns) - options_.trail_s) {
    trail_.pop_front();
  }

  JsonWriter j;
  j.begin_object().field("seq", js.seq).field("run_id", messages::run_id_text(js.run_id));
  j.field("utime", js.utime).field("t", seconds(js.mono_ns));
  write_joint_arrays(j, js);
  j.key("frames").begin_array();
  for (const auto& f : frames_) write_vec(j, f);
  j.end_array();
  j.key("palm");
  write_vec(j, palm);
  j.key("elbow");
  write_vec(j, elbow_fk);
  j.key("published");
  const std::optional<double> fk_error = write_published(j, js, palm, elbow_fk);
  // Computed palm and elbow minus the published ones for the same cycle: not
  // ~0 means this view's model or calibration is not the daemon's.
  j.key("fk_error_m");
  fk_error ? j.value(*fk_error) : j.null();
  j.key("rate_hz");
  const auto rate = meter_.rate_hz();
  rate ? j.value(*rate) : j.null();
  j.field("decimated", since_frame_);
  j.end_object();
  since_frame_ = 0;
  return j.str();
}

void ViewScene::write_joint_arrays(JsonWriter& j, const Joints& js) const {
  j.key("names").begin_array();
  for (const auto& name : model_.joint_names) j.value(name);
  j.end_array();
  j.key("q");
  write_array(j, js.q);
  j.key("qd");
  write_array(j, js.qd);
  j.key("homed");
  write_array(j, js.homed);
  j.key("flags");
  write_array(j, js.flags);
  j.key("flag_names").begin_array();
  for (const int32_t f : js.flags) j.value(messages::joint_flag_names(f));
  j.end_array();
  j.key("class").begin_array();
  for (int i = 0; i < kViewJoints; ++i) {
    j.value(
        joint_class(js.homed[static_cast<std::size_t>(i)], js.flags[static_cast<std::size_t>(i)]));
  }
  j.end_array();
  j.field("sample_flags", js.sample_flags)
      .field("sample_flag_names", messages::sample_flag_names(js.sample_flags));
}

std::optional<double> ViewScene::write_published(JsonWriter& j, const Joints& js,
                                                 const Eigen::Vector3d& palm,
                                                 const Eigen::Vector3d& elbow) const {
  if (!palm_) {
    j.null();
    return std::nullopt;
  }
  const Palm& p = *palm_;
  const Eigen::Vector3d pp(p.position[0], p.position[1], p.position[2]);
  const Eigen::Vector3d pe(p.elbow[0], p.elbow[1], p.elbow[2]);
  j.begin_object().field("seq", p.seq).field("valid", p.valid);
  j.field("invalid_reason", p.invalid_reason)
      .field("invalid_names", messages::invalid_reason_names(p.invalid_reason));
  j.key("position");
  write_vec(j, pp);
  j.key("elbow");
  write_vec(j, pe);
  j.field("manipulability", p.manipulability).field("near_singular", p.near_singular);
  j.end_object();
  if (p.seq != js.seq || p.run_id != js.run_id) return std::nullopt;
  return std::max((pp - palm).norm(), (pe - elbow).norm());
}

std::string ViewScene::status_json(const status_t& s) const {
  JsonWriter j;
  j.begin_object()
      .field("seq", s.seq)
      .field("utime", s.utime)
      .field("run_id", messages::run_id_text(s.run_id));
  j.field("rig", s.rig).field("state", messages::state_name(s.state));
  j.field("message", s.message).field("source", s.source);
  j.field("bus", messages::bus_state_name(s.bus_state)).field("board_errors", s.board_errors);
  j.key("clock").begin_object();
  j.field("synchronised", s.clock_synchronised != 0).field("required", options_.sync_required);
  // The kernel's 16 s bound means "no estimate" (clock_text.hpp): null.
  for (const auto& [key, us] : {std::pair{"est_error_us", s.clock_est_error_us},
                                std::pair{"max_error_us", s.clock_max_error_us}}) {
    j.key(key);
    clock_error_known(us) ? j.value(us) : j.null();
  }
  j.field("offset_us", s.clock_offset_us);
  j.field("utime_correction_us", s.utime_correction_us).field("steps", s.clock_steps);
  j.end_object();
  j.key("loop").begin_object();
  j.field("window_cycles", s.window_cycles).field("period_p50_us", s.period_p50_us);
  j.field("lateness_p99_us", s.lateness_p99_us).field("lateness_max_us", s.lateness_max_us);
  j.field("work_p99_us", s.work_p99_us).field("overruns", s.overruns);
  j.field("cycles", s.cycles).field("publish_failures", s.publish_failures);
  j.end_object();
  j.key("source_stats").begin_object();
  j.field("frames", s.frames).field("bad_frames", s.bad_frames);
  j.field("missing_samples", s.missing_samples).field("seq_gaps", s.seq_gaps);
  j.field("bus_errors", s.bus_errors);
  j.end_object();
  // The backend's own state and counters, from the source_status_t of the same run.
  j.key("backend");
  if (source_status_ && source_status_->run_id == s.run_id) {
    const source_status_t& b = *source_status_;
    j.begin_object().field("state", b.state).key("counters").begin_object();
    for (std::size_t i = 0; i < messages::counters_in(b); ++i)
      j.field(b.counter_name[i], b.counter_value[i]);
    j.end_object().end_object();
  } else {
    j.null();
  }
  j.key("homing").begin_array();
  for (const int8_t h : s.homing) j.value(messages::homing_name(h));
  j.end_array();
  j.key("joint_flags").begin_array();
  for (const int32_t f : s.joint_flags) j.value(messages::joint_flag_names(f));
  j.end_array();
  j.end_object();
  return j.str();
}

std::vector<SceneEvent> ViewScene::tick(int64_t now_ns) {
  std::vector<SceneEvent> events;
  if (joint_dirty_ && joints_) {
    last_frame_json_ = frame_json();
    events.push_back(SceneEvent{"frame", last_frame_json_, true});
    joint_dirty_ = false;
  }
  if (status_dirty_ && status_) {
    last_status_json_ = status_json(*status_);
    events.push_back(SceneEvent{"status", last_status_json_, true});
    status_dirty_ = false;
  }
  const StreamState s = stream_state(now_ns);
  if (!last_sent_state_ || *last_sent_state_ != s ||
      seconds(now_ns - last_stream_ns_) >= options_.stream_every_s) {
    // Not skippable: a change of state must reach every page.
    events.push_back(SceneEvent{"stream", stream_json(now_ns), false});
    last_sent_state_ = s;
    last_stream_ns_ = now_ns;
  }
  return events;
}

std::string ViewScene::model_json() const {
  JsonWriter j;
  j.begin_object().field("name", model_.name).field("file", model_.model_file);
  j.field("calibrated", model_.calibrated);
  j.field("joints", kViewJoints).field("frames", model_.chain.joint_count() + 2);
  j.field("elbow_frame", model_.elbow_frame).field("reach_m", reach_m_);
  j.key("joint_names").begin_array();
  for (const auto& n : model_.joint_names) j.value(n);
  j.end_array();
  j.key("limits").begin_array();
  for (const auto& l : model_.joint_limits) j.begin_array().value(l[0]).value(l[1]).end_array();
  j.end_array();
  j.end_object();
  return j.str();
}

std::string ViewScene::hello(int64_t now_ns) const {
  JsonWriter j;
  j.begin_object();
  j.key("view").begin_object();
  j.field("version", std::string(kVersion) + " (" + kGitDescribe + ")");
  j.field("url", options_.url).field("prefix", options_.prefix);
  j.field("config", model_.config_file).field("rig", model_.rig);
  j.field("display_hz", options_.display_hz).field("trail_s", options_.trail_s);
  j.field("silence_s", options_.silence_s);
  j.end_object();
  j.key("model").raw(model_json());
  j.key("trail").begin_array();
  for (const auto& p : trail_)
    j.begin_array().value(p.t).value(p.p.x()).value(p.p.y()).value(p.p.z()).end_array();
  j.end_array();
  j.key("frame");
  last_frame_json_.empty() ? j.null() : j.raw(last_frame_json_);
  j.key("status");
  last_status_json_.empty() ? j.null() : j.raw(last_status_json_);
  j.key("stream").raw(stream_json(now_ns));
  j.end_object();
  return j.str();
}

}  // namespace exodaq::tools::view
