#pragma once
// What `exodaq view` shows, decimated from the 1 kHz stream to display rate:
// the last joint state with the origin of every model frame (forward
// kinematics of the published angles, frame 0 = O0 .. n + 1 = palm), the
// joints' flag classes, the published palm pose beside the computed one, the
// palm trail of the last few seconds, the last status, and the stream's state
// (waiting / live / no-data / stopped). Messages go in at any rate; tick()
// hands out JSON events at most once per call. Times are the caller's
// CLOCK_MONOTONIC ns, so tests drive it without sleeping. docs/operations.md.
#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "exodaq/joint_state_t.hpp"
#include "exodaq/kinematics/chain.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/source_status_t.hpp"
#include "exodaq/status_t.hpp"
#include "exodaq/wire_constants.hpp"
#include "rate_meter.hpp"

namespace exodaq::tools::view {

class JsonWriter;

inline constexpr int kViewJoints = wire::kJointCount;  // joint_state_t's joints

struct ViewModel {
  std::string name;         // the model's name
  std::string model_file;   // where it was read from
  std::string config_file;  // the service config it came with (empty: --model)
  std::string rig;          // the config's rig name (empty: --model)
  bool calibrated = false;  // the chain has the config's calibration applied
  kinematics::Chain chain;  // must have kViewJoints joints
  int elbow_frame = 4;
  std::vector<std::string> joint_names;             // the model's, until messages name them
  std::vector<std::array<double, 2>> joint_limits;  // rad
};

struct SceneOptions {
  std::string url;     // shown on the page
  std::string prefix;  // channel prefix
  double display_hz = 30.0;
  double trail_s = 5.0;         // palm trail length
  double silence_s = 1.0;       // no joint state for longer: "no-data" (or "stopped")
  double stream_every_s = 0.5;  // a stream event at least this often
  bool sync_required = true;    // false under the config's clock.require_sync: ignore
};

enum class StreamState { kWaiting, kLive, kNoData, kStopped };
std::string_view stream_state_name(StreamState s);

// Per-joint class for colouring: "ok", "unhomed" (not homed yet), "held"
// (value held, no new count this cycle) or "fault" (any other flag).
std::string_view joint_class(bool homed, int32_t flags);

struct SceneEvent {
  std::string name;  // SSE event name: frame, status, stream
  std::string json;
  bool skippable = true;  // a later event of the same name supersedes it
};

class ViewScene {
 public:
  // Throws std::invalid_argument when the chain does not have six joints.
  ViewScene(ViewModel model, SceneOptions options);

  void on_joint_state(const joint_state_t& m, int64_t now_ns);
  void on_palm_pose(const palm_pose_t& m, int64_t now_ns);
  void on_status(const status_t& m, int64_t now_ns);
  // The backend's state and counters: part of the next status event.
  void on_source_status(const source_status_t& m);

  // Events since the last tick: a frame when a joint state arrived, a status
  // when one arrived, a stream event when the state changed or every
  // stream_every_s. Forward kinematics runs here, once per frame.
  std::vector<SceneEvent> tick(int64_t now_ns);

  // The first event of a new page: model, view settings, trail, and the last
  // frame, status and stream state, so it draws at once.
  std::string hello(int64_t now_ns) const;
  std::string stream_json(int64_t now_ns) const;
  StreamState stream_state(int64_t now_ns) const;

  // Frame origins (m, O0) of the last frame tick() produced; empty before.
  const std::vector<Eigen::Vector3d>& frames() const { return frames_; }
  int64_t frames_built() const { return frames_built_; }

 private:
  struct Joints {
    int64_t seq = 0, run_id = 0, utime = 0, mono_ns = 0;
    std::array<double, kViewJoints> q{}, qd{};
    std::array<bool, kViewJoints> homed{};
    std::array<int32_t, kViewJoints> flags{};
    int32_t sample_flags = 0;
  };
  struct Palm {
    int64_t seq = 0, run_id = 0;
    bool valid = false;
    int32_t invalid_reason = 0;
    std::array<double, 3> position{}, elbow{};
    double manipulability = 0.0;
    bool near_singular = false;
  };
  struct TrailPoint {
    double t;  // publisher's mono_ns in s
    Eigen::Vector3d p;
  };

  std::string frame_json();
  void write_joint_arrays(JsonWriter& j, const Joints& js) const;
  // The published palm pose (null without one); returns the distance from
  // `palm`/`elbow` (this view's FK) when it is for the same cycle.
  std::optional<double> write_published(JsonWriter& j, const Joints& js,
                                        const Eigen::Vector3d& palm,
                                        const Eigen::Vector3d& elbow) const;
  std::string status_json(const status_t& s) const;
  std::string model_json() const;

  ViewModel model_;
  SceneOptions options_;
  double reach_m_ = 0.0;

  std::optional<Joints> joints_;
  std::optional<Palm> palm_;
  std::optional<status_t> status_;
  std::optional<source_status_t> source_status_;
  int64_t joint_local_ns_ = 0;
  int64_t status_local_ns_ = 0;
  int64_t joint_messages_ = 0;
  int64_t since_frame_ = 0;  // joint states received since the last frame
  bool joint_dirty_ = false;
  bool status_dirty_ = false;
  RateMeter meter_;

  std::vector<Eigen::Vector3d> frames_;
  int64_t frames_built_ = 0;
  std::deque<TrailPoint> trail_;
  std::string last_frame_json_;
  std::string last_status_json_;
  std::optional<StreamState> last_sent_state_;
  int64_t last_stream_ns_ = 0;
};

}  // namespace exodaq::tools::view
