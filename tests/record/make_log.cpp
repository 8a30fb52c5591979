// A daemon's recording of any length, written with the log writer (as
// exodaq record or lcm-logger would have recorded it), for the damage tests
// and their one-off measurement on an hour's log (docs/robustness.md):
//   exodaq_test_make_log OUT.lcm CYCLES [PREFIX]
// Per cycle seq (1 kHz): encoder_raw_t (the test support's raw_message),
// joint_state_t and palm_pose_t of that seq; a status_t after every 100th.
#include <cstdio>
#include <cstdlib>
#include <string>

#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "sample_messages.hpp"

int main(int argc, char** argv) {
  using namespace exodaq;
  if (argc < 3 || argc > 4) {
    std::fprintf(stderr, "usage: %s OUT.lcm CYCLES [PREFIX]\n", argv[0]);
    return 2;
  }
  const std::string prefix = argc == 4 ? argv[3] : "";
  const long long cycles = std::atoll(argv[2]);
  const std::string raw_ch = messages::channel_name(prefix, messages::Kind::kEncoderRaw);
  const std::string joint_ch = messages::channel_name(prefix, messages::Kind::kJointState);
  const std::string palm_ch = messages::channel_name(prefix, messages::Kind::kPalmPose);
  const std::string status_ch = messages::channel_name(prefix, messages::Kind::kStatus);
  try {
    messages::LogWriter log(argv[1]);
    joint_state_t j{};
    const char* names[6] = {"shoulder_azimuth",  "shoulder_abduction", "shoulder_flexion",
                            "shoulder_rotation", "elbow_flexion",      "forearm_pronation"};
    for (int i = 0; i < 6; ++i) j.name[i] = names[i];
    palm_pose_t p{};
    status_t s{};
    s.rig = "make-log";
    s.state = status_t::STATE_RUNNING;
    for (int i = 0; i < 6; ++i) s.joint_name[i] = names[i];
    for (long long seq = 0; seq < cycles; ++seq) {
      const encoder_raw_t r = test::raw_message(seq);
      const auto put = [&](const std::string& ch, const auto& m) {
        const auto bytes = messages::encode(m);
        log.write(ch, r.utime + 150, bytes.data(), bytes.size());
      };
      put(raw_ch, r);
      j.utime = p.utime = r.utime;
      j.mono_ns = p.mono_ns = r.mono_ns;
      j.seq = p.seq = seq;
      j.run_id = p.run_id = r.run_id;
      for (int i = 0; i < 6; ++i) {
        j.position[i] = 0.001 * static_cast<double>(seq % 1000) + 0.1 * i;
        j.velocity[i] = 0.5 + 0.01 * i;
        j.raw_count[i] = r.position[i];
        j.homed[i] = 1;
      }
      put(joint_ch, j);
      p.valid = 1;
      p.position[0] = 0.01 * static_cast<double>(seq % 100);
      p.orientation[0] = 1.0;
      put(palm_ch, p);
      if (seq % 100 == 99) {
        s.utime = r.utime;
        s.mono_ns = r.mono_ns;
        s.seq = seq;
        s.run_id = r.run_id;
        s.cycles = seq + 1;
        s.window_cycles = 100;
        put(status_ch, s);
      }
    }
    log.close();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
