// The scene of `exodaq view`: frame origins from the published angles (golden
// values of docs/kinematics.md at the home posture), one frame per display
// tick whatever the message rate, the stream's states, the palm trail, the
// model-mismatch check, and the JSON text the page parses.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <numbers>
#include <string>

#include "exodaq/settings/model_file.hpp"
#include "view_json.hpp"
#include "view_scene.hpp"

namespace exodaq::tools::view {
namespace {

constexpr int64_t kMs = 1'000'000;
constexpr int64_t kSecond = 1'000'000'000;
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kL1 = 0.145, kL2 = 0.152;  // config/models/macaque_exo.yaml d4, d6

ViewModel macaque() {
  const auto m =
      settings::load_model_file(std::string(EXODAQ_SOURCE_DIR) + "/config/models/macaque_exo.yaml");
  ViewModel v;
  v.name = m.name;
  v.model_file = m.file;
  v.chain = m.chain;
  v.elbow_frame = m.rig.elbow_frame;
  for (const auto& j : m.chain.joints()) {
    v.joint_names.push_back(j.name);
    v.joint_limits.push_back({j.limits.lower, j.limits.upper});
  }
  return v;
}

joint_state_t joints(int64_t seq, const std::array<double, 6>& deg, int64_t run_id = 42) {
  joint_state_t m{};
  m.seq = seq;
  m.run_id = run_id;
  m.mono_ns = seq * kMs;  // the daemon's 1 kHz cycle
  m.utime = 1'800'000'000'000'000 + seq * 1000;
  for (int i = 0; i < 6; ++i) {
    m.name[i] = "j" + std::to_string(i + 1);
    m.position[i] = deg[static_cast<std::size_t>(i)] * kDeg;
    m.homed[i] = 1;
  }
  return m;
}

const std::array<double, 6> kHome{45, -90, 90, 0, 0, 0};

// The number after "key": in a JSON text (first occurrence); NaN if absent or null.
double number_after(const std::string& json, const std::string& key) {
  const auto at = json.find("\"" + key + "\":");
  if (at == std::string::npos) return std::nan("");
  const char* p = json.c_str() + at + key.size() + 3;
  char* end = nullptr;
  const double v = std::strtod(p, &end);
  return end == p ? std::nan("") : v;
}

std::vector<SceneEvent> named(const std::vector<SceneEvent>& events, const std::string& name) {
  std::vector<SceneEvent> out;
  for (const auto& e : events)
    if (e.name == name) out.push_back(e);
  return out;
}

TEST(ViewScene, HomePostureFramesAreTheGoldenOnes) {
  ViewScene scene(macaque(), SceneOptions{});
  scene.on_joint_state(joints(1, kHome), kSecond);
  const auto frames = named(scene.tick(kSecond), "frame");
  ASSERT_EQ(frames.size(), 1u);
  const auto& f = scene.frames();
  ASSERT_EQ(f.size(), 8u);  // O0, frames 1..6, palm
  EXPECT_LT(f[0].norm(), 1e-15);
  // docs/kinematics.md: at the home posture the arm hangs straight down.
  EXPECT_LT((f[4] - Eigen::Vector3d(0, 0, -kL1)).norm(), 1e-12) << f[4].transpose();
  EXPECT_LT((f[7] - Eigen::Vector3d(0, 0, -(kL1 + kL2))).norm(), 1e-12) << f[7].transpose();
  // And every frame is the chain's own.
  const auto model = macaque();
  kinematics::JointVector q(6);
  for (int i = 0; i < 6; ++i) q[i] = kHome[static_cast<std::size_t>(i)] * kDeg;
  for (int i = 0; i < 8; ++i) {
    EXPECT_LT((f[static_cast<std::size_t>(i)] - model.chain.frame(q, i).translation()).norm(),
              1e-15)
        << "frame " << i;
  }
  const std::string& j = frames[0].json;
  EXPECT_NE(j.find("\"class\":[\"ok\",\"ok\",\"ok\",\"ok\",\"ok\",\"ok\"]"), std::string::npos)
      << j;
  EXPECT_NE(j.find("\"names\":[\"j1\",\"j2\""), std::string::npos) << j;
  EXPECT_NE(j.find("\"run_id\":\"000000000000002a\""), std::string::npos) << j;
  EXPECT_DOUBLE_EQ(number_after(j, "seq"), 1.0);
}

TEST(ViewScene, SegmentLengthsHoldInAnyPosture) {
  ViewScene scene(macaque(), SceneOptions{});
  scene.on_joint_state(joints(1, {100, -30, 40, 60, -70, 20}), kSecond);
  scene.tick(kSecond);
  const auto& f = scene.frames();
  EXPECT_NEAR((f[4] - f[0]).norm(), kL1, 1e-12);
  EXPECT_NEAR((f[7] - f[4]).norm(), kL2, 1e-12);
}

TEST(ViewScene, OneFramePerTickWhateverTheMessageRate) {
  ViewScene scene(macaque(), SceneOptions{});
  for (int64_t s = 1; s <= 1000; ++s) scene.on_joint_state(joints(s, kHome), kSecond + s * kMs);
  const int64_t now = 2 * kSecond;
  auto frames = named(scene.tick(now), "frame");
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_DOUBLE_EQ(number_after(frames[0].json, "seq"), 1000.0);  // the newest
  EXPECT_DOUBLE_EQ(number_after(frames[0].json, "decimated"), 1000.0);
  EXPECT_EQ(scene.frames_built(), 1);
  // Nothing new: no frame (and no forward kinematics) on the next tick.
  EXPECT_TRUE(named(scene.tick(now + 33 * kMs), "frame").empty());
  EXPECT_EQ(scene.frames_built(), 1);
}

TEST(ViewScene, StreamStatesWaitingLiveNoDataStoppedAndANewRun) {
  SceneOptions o;
  ViewScene scene(macaque(), o);
  int64_t now = kSecond;
  auto stream = [&] {
    const auto e = named(scene.tick(now), "stream");
    return e.empty() ? std::string() : e[0].json;
  };
  EXPECT_NE(stream().find("\"state\":\"waiting\""), std::string::npos);
  now += 100 * kMs;
  EXPECT_EQ(stream(), "");  // unchanged and not yet due
  now += 500 * kMs;
  EXPECT_NE(stream().find("\"state\":\"waiting\""), std::string::npos);  // due every 0.5 s

  scene.on_joint_state(joints(1, kHome), now);
  const auto events = scene.tick(now);
  const auto live = named(events, "stream");
  ASSERT_EQ(live.size(), 1u);  // the change goes out at once
  EXPECT_NE(live[0].json.find("\"state\":\"live\""), std::string::npos);
  EXPECT_FALSE(live[0].skippable);

  now += 900 * kMs;
  EXPECT_EQ(scene.stream_state(now), StreamState::kLive);
  now += 200 * kMs;  // 1.1 s of silence
  const std::string nodata = stream();
  EXPECT_NE(nodata.find("\"state\":\"no-data\""), std::string::npos) << nodata;
  EXPECT_NE(nodata.find("nothing on EXO_JOINT_STATE for 1.1 s"), std::string::npos) << nodata;

  status_t stopping{};
  stopping.run_id = 42;
  stopping.state = status_t::STATE_STOPPING;
  scene.on_status(stopping, now);
  const auto ev = scene.tick(now);
  ASSERT_EQ(named(ev, "status").size(), 1u);
  EXPECT_NE(named(ev, "status")[0].json.find("\"state\":\"STOPPING\""), std::string::npos);
  ASSERT_EQ(named(ev, "stream").size(), 1u);
  EXPECT_NE(named(ev, "stream")[0].json.find("\"state\":\"stopped\""), std::string::npos);

  // A new daemon run: live again.
  now += kSecond;
  scene.on_joint_state(joints(1, kHome, 43), now);
  EXPECT_EQ(scene.stream_state(now), StreamState::kLive);
  EXPECT_NE(stream().find("\"run_id\":\"000000000000002b\""), std::string::npos);
}

TEST(ViewScene, StoppingStatusWithTheStreamStillFlowingIsNotStopped) {
  ViewScene scene(macaque(), SceneOptions{});
  status_t stopping{};
  stopping.state = status_t::STATE_STOPPING;
  scene.on_status(stopping, kSecond);
  EXPECT_EQ(scene.stream_state(kSecond), StreamState::kStopped);
  scene.on_joint_state(joints(5, kHome), kSecond + kMs);  // a joint state after it
  EXPECT_EQ(scene.stream_state(kSecond + kMs), StreamState::kLive);
}

// The kernel's 16 s error bound (no NTP estimate) is null (the page says
// "unknown"), for the estimated and the maximum error alike, and an
// unsynchronised clock the config ignores is said to be ignored (issue 16.9).
TEST(ViewScene, ClockWithoutAnEstimateUnderRequireSyncIgnore) {
  SceneOptions ignoring;
  ignoring.sync_required = false;
  ViewScene scene(macaque(), ignoring);
  status_t s{};
  s.clock_synchronised = false;
  s.clock_est_error_us = 16'000'000.0;
  s.clock_max_error_us = 16'000'000.0;
  s.state = status_t::STATE_DEGRADED;
  scene.on_status(s, kSecond);
  const auto ev = named(scene.tick(kSecond), "status");
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_NE(ev[0].json.find("\"synchronised\":false,\"required\":false,\"est_error_us\":null,"
                            "\"max_error_us\":null,"),
            std::string::npos)
      << ev[0].json;
  // The state by name only: no numeric code beside it.
  EXPECT_NE(ev[0].json.find("\"state\":\"DEGRADED\","), std::string::npos) << ev[0].json;
  EXPECT_EQ(ev[0].json.find("state_code"), std::string::npos) << ev[0].json;

  ViewScene strict(macaque(), SceneOptions{});
  s.clock_synchronised = true;
  s.clock_est_error_us = 250.0;
  s.clock_max_error_us = 1500.5;
  strict.on_status(s, kSecond);
  const auto ev2 = named(strict.tick(kSecond), "status");
  ASSERT_EQ(ev2.size(), 1u);
  EXPECT_NE(ev2[0].json.find("\"synchronised\":true,\"required\":true,\"est_error_us\":250,"
                             "\"max_error_us\":1500.5,"),
            std::string::npos)
      << ev2[0].json;
}

// The backend's state and counters (source_status_t) ride on the status
// event of the same run; another run's are not shown as this one's.
TEST(ViewScene, TheStatusCarriesTheBackendOfTheSameRun) {
  ViewScene scene(macaque(), SceneOptions{});
  status_t s{};
  s.run_id = 77;
  scene.on_status(s, kSecond);
  auto ev = named(scene.tick(kSecond), "status");
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_NE(ev[0].json.find("\"backend\":null"), std::string::npos) << ev[0].json;

  source_status_t b{};
  b.run_id = 77;
  b.state = "can0 down: ENODEV";
  b.counter_count = 2;
  b.counter_name = {"interface_losses", "reopens"};
  b.counter_value = {3, 2};
  scene.on_source_status(b);
  ev = named(scene.tick(kSecond + kMs), "status");
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_NE(ev[0].json.find("\"backend\":{\"state\":\"can0 down: ENODEV\",\"counters\":{"
                            "\"interface_losses\":3,\"reopens\":2}}"),
            std::string::npos)
      << ev[0].json;

  b.run_id = 78;  // another daemon's
  scene.on_source_status(b);
  ev = named(scene.tick(kSecond + 2 * kMs), "status");
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_NE(ev[0].json.find("\"backend\":null"), std::string::npos) << ev[0].json;
}

TEST(ViewScene, TrailKeepsTheLastSecondsAndRestartsWithARun) {
  SceneOptions o;
  o.trail_s = 2.0;
  ViewScene scene(macaque(), o);
  // 6 s of the 1 kHz stream, one frame per 33 ms tick.
  int64_t seq = 0;
  for (int64_t now = kSecond; now < 7 * kSecond; now += 33 * kMs) {
    for (int k = 0; k < 33; ++k) {
      ++seq;
      scene.on_joint_state(joints(seq, {45, -90 + seq * 0.01, 90, 0, 0, 0}), now);
    }
    scene.tick(now);
  }
  auto trail_points = [&] {
    const std::string h = scene.hello(7 * kSecond);
    const auto a = h.find("\"trail\":[");
    const auto b = h.find("]],", a);
    if (h.compare(a, 10, "\"trail\":[]") == 0 || b == std::string::npos) return 0;
    int n = 0;
    for (auto i = a; i <= b; ++i) n += h[i] == '[';
    return n - 1;
  };
  // 2 s of 33-cycle frames: 61 points (both ends included), not 6 s worth.
  EXPECT_EQ(trail_points(), 61);
  scene.on_joint_state(joints(1, kHome, 99), 7 * kSecond);
  scene.tick(7 * kSecond);
  EXPECT_EQ(trail_points(), 1);
}

TEST(ViewScene, PublishedPalmOffTheComputedOneShowsAsModelMismatch) {
  ViewScene scene(macaque(), SceneOptions{});
  palm_pose_t p{};
  p.seq = 7;
  p.run_id = 42;
  p.position[2] = -(kL1 + kL2);
  p.elbow[2] = -kL1;
  scene.on_palm_pose(p, kSecond);
  scene.on_joint_state(joints(7, kHome), kSecond);
  auto f = named(scene.tick(kSecond), "frame");
  ASSERT_EQ(f.size(), 1u);
  EXPECT_LT(number_after(f[0].json, "fk_error_m"), 1e-12) << f[0].json;

  p.seq = 8;
  p.position[0] = 0.005;  // 5 mm off: another model or calibration
  scene.on_palm_pose(p, kSecond);
  scene.on_joint_state(joints(8, kHome), kSecond);
  f = named(scene.tick(kSecond + 33 * kMs), "frame");
  ASSERT_EQ(f.size(), 1u);
  EXPECT_NEAR(number_after(f[0].json, "fk_error_m"), 0.005, 1e-12);

  // Different cycles are not compared.
  scene.on_joint_state(joints(9, kHome), kSecond);
  f = named(scene.tick(kSecond + 66 * kMs), "frame");
  EXPECT_NE(f[0].json.find("\"fk_error_m\":null"), std::string::npos) << f[0].json;
}

TEST(ViewScene, JointClassesFromTheFlags) {
  const int32_t unhomed = joint_state_t::JOINT_UNHOMED;
  const int32_t held = joint_state_t::JOINT_HELD;
  EXPECT_EQ(joint_class(true, 0), "ok");
  EXPECT_EQ(joint_class(false, 0), "unhomed");
  EXPECT_EQ(joint_class(false, unhomed), "unhomed");
  EXPECT_EQ(joint_class(false, unhomed | held), "unhomed");
  EXPECT_EQ(joint_class(true, held), "held");
  const int32_t faults[] = {joint_state_t::JOINT_STALE,           joint_state_t::JOINT_GLITCH,
                            joint_state_t::JOINT_OUT_OF_RANGE,    joint_state_t::JOINT_LOST_COUNTS,
                            joint_state_t::JOINT_HOMING_REJECTED, joint_state_t::JOINT_BOARD_ERROR};
  for (const int32_t f : faults) {
    EXPECT_EQ(joint_class(true, f), "fault") << f;
    EXPECT_EQ(joint_class(false, f | unhomed), "fault") << f;
  }
}

TEST(ViewScene, AModelWithoutSixJointsIsRefused) {
  ViewModel m = macaque();
  std::vector<kinematics::JointDescription> five(m.chain.joints().begin(),
                                                 m.chain.joints().end() - 1);
  m.chain = kinematics::Chain(kinematics::Convention::kStandardDh, five,
                              kinematics::Pose::Identity(), kinematics::Pose::Identity());
  try {
    ViewScene scene(m, SceneOptions{});
    FAIL() << "a five-joint model was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("has 5 joints"), std::string::npos) << e.what();
  }
}

TEST(ViewJson, EscapesAndNesting) {
  JsonWriter j;
  j.begin_object().field("s", "a\"b\\c\nd\x01").field("n", std::nan("")).field("i", int64_t{-3});
  j.key("a").begin_array().value(0.1).value(true).null().begin_object().end_object().end_array();
  j.field("x", 1e-300).end_object();
  EXPECT_EQ(j.str(),
            "{\"s\":\"a\\\"b\\\\c\\u000ad\\u0001\",\"n\":null,\"i\":-3,\"a\":[0.1,true,null,{}],"
            "\"x\":1e-300}");
}

}  // namespace
}  // namespace exodaq::tools::view
