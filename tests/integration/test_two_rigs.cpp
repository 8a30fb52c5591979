// Two rigs on one host (issue 19 point 2; docs/operations.md "Several rigs"):
// two exodaqd processes on the simulated rig, each with its own config (rig
// name, lcm.prefix, sim seed), on one LCM group. One recorder hears every
// channel of both prefixes and must find each rig's messages on its own
// channels only: one run id per prefix (the one its status names), seq
// strictly increasing per channel, joint angles equal to that rig's own
// simulator truth. `exodaq status --prefix` selects each rig by prefix and
// names it; each daemon's log lines name its rig.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <thread>

#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/drivers/source_factory.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq/settings/service_config.hpp"
#include "process.hpp"
#include "recording.hpp"
#include "sim_daemon.hpp"
#include "status_wait.hpp"

using namespace exodaq;
using namespace std::chrono_literals;

namespace {

struct RigSetup {
  std::string name;    // config `rig:`
  std::string prefix;  // config lcm.prefix
  std::string dir;
  std::string config;
};

// config/sim.yaml under its own rig name, prefix and sim seed.
RigSetup make_rig(const std::string& name, const std::string& tag, int seed) {
  RigSetup r;
  r.name = name;
  r.prefix = test::unique_prefix(tag);
  r.dir = test::make_temp_dir("two-rigs-" + tag);
  r.config = test::write_sim_config(r.dir, r.prefix);
  std::string text = test::read_file(r.config);
  text = std::regex_replace(text, std::regex("\nrig: [^\n]*"), "\nrig: " + name);
  text = std::regex_replace(text, std::regex("seed: 1\n"), "seed: " + std::to_string(seed) + "\n");
  std::ofstream(r.config) << text;
  return r;
}

// What the recorder heard on one rig's channels.
struct Heard {
  std::map<messages::Kind, std::int64_t> count;
  std::map<messages::Kind, std::int64_t> last_seq;
  std::set<std::int64_t> run_ids;
  std::set<std::string> status_rigs;
  std::int64_t out_of_order = 0;
};

}  // namespace

TEST(TwoRigs, EachRigsMessagesOnlyOnItsOwnChannelsAndToolsSelectByPrefix) {
  const RigSetup a = make_rig("rig-a", "riga", 1);
  const RigSetup b = make_rig("rig-b", "rigb", 7);
  ASSERT_NE(a.prefix, b.prefix);
  // Every channel of both prefixes (and anything else starting like them).
  const std::string common = test::unique_prefix("rig");  // "T<pid>_rig_"
  const std::string pattern = messages::regex_escape(common.substr(0, common.size() - 1)) + ".*";
  test::Process recorder({EXODAQ_RECORDER, test::kRecordUrl, pattern, a.dir + "/rec.bin"}, "",
                         a.dir + "/rec.err");
  ASSERT_TRUE(test::wait_for_udp_socket(recorder.pid(), 7667));
  test::Process da({EXODAQD, "--config", a.config}, a.dir + "/d.out", a.dir + "/d.err");
  test::Process db({EXODAQD, "--config", b.config}, b.dir + "/d.out", b.dir + "/d.err");
  // Joint 1 homes at ~0.95 s of each rig's time: until each rig's status says so.
  for (const RigSetup* r : {&a, &b}) {
    EXPECT_NE(test::wait_for_status(
                  test::kLcmUrl, r->prefix,
                  [](const status_t& st) { return st.homing[0] == status_t::HOMING_HOMED; })
                  .run_id,
              0)
        << r->name << ": joint 1 never homed";
  }

  // The tools select a rig by prefix, and name it.
  const auto status_a = test::run(
      {EXODAQ_TOOL, "status", "--prefix", a.prefix, "--url", test::kLcmUrl, "--timeout", "10"});
  const auto status_b = test::run(
      {EXODAQ_TOOL, "status", "-p", b.prefix, "--url", test::kLcmUrl, "--timeout", "10", "--json"});
  const auto status_none = test::run(
      {EXODAQ_TOOL, "status", "-p", common + "none_", "--url", test::kLcmUrl, "--timeout", "1"});
  const auto bad_prefix = test::run({EXODAQ_TOOL, "status", "-p", "rig b"});

  da.signal(SIGTERM);
  db.signal(SIGTERM);
  ASSERT_EQ(da.wait(10s).value_or(-1), 0);
  ASSERT_EQ(db.wait(10s).value_or(-1), 0);
  std::this_thread::sleep_for(300ms);
  recorder.signal(SIGTERM);
  recorder.wait(5s);

  EXPECT_EQ(status_a.exit_code, 0) << status_a.err;
  EXPECT_NE(status_a.out.find(a.prefix + "EXO_STATUS  rig 'rig-a'"), std::string::npos)
      << status_a.out;
  EXPECT_EQ(status_b.exit_code, 0) << status_b.err;
  EXPECT_NE(status_b.out.find("\"rig\": \"rig-b\""), std::string::npos) << status_b.out;
  EXPECT_EQ(status_b.out.find("rig-a"), std::string::npos) << status_b.out;
  EXPECT_EQ(status_none.exit_code, 1);  // a prefix no rig uses: nothing heard
  EXPECT_EQ(bad_prefix.exit_code, 2) << bad_prefix.err;
  EXPECT_NE(bad_prefix.err.find("letters, digits and _ - . / only"), std::string::npos)
      << bad_prefix.err;

  // Each daemon's log lines name its rig, and only its rig.
  const std::string log_a = test::read_file(a.dir + "/d.err");
  const std::string log_b = test::read_file(b.dir + "/d.err");
  EXPECT_NE(log_a.find("[rig-a] info exodaqd"), std::string::npos) << log_a;
  EXPECT_NE(log_b.find("[rig-b] info exodaqd"), std::string::npos) << log_b;
  EXPECT_EQ(log_a.find("rig-b"), std::string::npos) << log_a;
  EXPECT_EQ(log_b.find("rig-a"), std::string::npos) << log_b;

  // Each rig's truth, to check the angles on its channels are its own.
  struct Truth {
    std::unique_ptr<drivers::EncoderSource> source;
    const drivers::SimSource* sim = nullptr;
  };
  const auto truth_of = [](const RigSetup& r) {
    const auto cfg = settings::load_service_config(r.config);
    Truth t;
    t.source = drivers::make_source(cfg.source, settings::make_source_context(cfg));
    t.sim = dynamic_cast<const drivers::SimSource*>(t.source.get());
    return t;
  };
  const Truth ta = truth_of(a);
  const Truth tb = truth_of(b);
  ASSERT_NE(ta.sim, nullptr);
  ASSERT_NE(tb.sim, nullptr);
  const double count = 2.0 * M_PI / 10000.0;

  std::map<std::string, Heard> heard;  // by prefix
  std::int64_t foreign = 0;
  std::int64_t homed_checked = 0;
  std::int64_t truths_differ = 0;
  for (const auto& m : test::read_recorder_file(a.dir + "/rec.bin")) {
    const auto parts = messages::split_channel(m.channel);
    if (!parts || (parts->prefix != a.prefix && parts->prefix != b.prefix)) {
      ++foreign;
      ADD_FAILURE() << "message on an unexpected channel " << m.channel;
      continue;
    }
    const auto decoded = messages::decode(parts->kind, m.data.data(), m.data.size());
    ASSERT_TRUE(decoded.has_value()) << m.channel;
    ASSERT_EQ(messages::kind_of(*decoded), parts->kind) << m.channel;
    Heard& h = heard[parts->prefix];
    const messages::Stamp st = messages::stamp_of(*decoded);
    h.run_ids.insert(st.run_id);
    auto [it, first] = h.last_seq.try_emplace(parts->kind, st.seq);
    if (!first) {
      // The final status covers the cycles since the last window, possibly
      // none (the loop stopped right after a window closed): then it repeats
      // that window's seq (docs/messages.md, status_t.seq).
      const auto* status = std::get_if<status_t>(&*decoded);
      const bool empty_final =
          status != nullptr && st.seq == it->second && status->state == status_t::STATE_STOPPING;
      if (st.seq <= it->second && !empty_final) ++h.out_of_order;
      it->second = st.seq;
    }
    ++h.count[parts->kind];
    if (const auto* s = std::get_if<status_t>(&*decoded)) h.status_rigs.insert(s->rig);
    if (const auto* js = std::get_if<joint_state_t>(&*decoded)) {
      const Truth& own = parts->prefix == a.prefix ? ta : tb;
      const Truth& other = parts->prefix == a.prefix ? tb : ta;
      const auto q = own.sim->rig().motion().truth(own.sim->rig().sample_time_s(js->seq)).position;
      const auto q_other =
          other.sim->rig().motion().truth(other.sim->rig().sample_time_s(js->seq)).position;
      for (int j = 0; j < 6; ++j) {
        if (!js->homed[j]) continue;
        ASSERT_LE(std::fabs(js->position[j] - q[j]), count + 1e-9)
            << m.channel << " seq " << js->seq << " joint " << j + 1 << ": not its own rig's angle";
        ++homed_checked;
        if (std::fabs(q[j] - q_other[j]) > 10 * count) ++truths_differ;
      }
    }
  }
  EXPECT_EQ(foreign, 0);
  ASSERT_EQ(heard.size(), 2U);
  for (const auto& [prefix, h] : heard) {
    SCOPED_TRACE(prefix);
    EXPECT_EQ(h.run_ids.size(), 1U) << "two daemons' messages on one prefix";
    EXPECT_EQ(h.out_of_order, 0) << "seq went back on a channel: another rig's message";
    EXPECT_EQ(h.status_rigs,
              (std::set<std::string>{prefix == a.prefix ? std::string("rig-a") : "rig-b"}));
    for (const auto k : messages::kAllKinds)
      EXPECT_GT(h.count.count(k), 0U);  // every kind published
  }
  std::printf(
      "two rigs: %lld + %lld joint states, %lld homed angles checked against their own "
      "truth, %lld of them differing from the other rig's truth\n",
      static_cast<long long>(heard[a.prefix].count[messages::Kind::kJointState]),
      static_cast<long long>(heard[b.prefix].count[messages::Kind::kJointState]),
      static_cast<long long>(homed_checked), static_cast<long long>(truths_differ));
  EXPECT_NE(*heard[a.prefix].run_ids.begin(), *heard[b.prefix].run_ids.begin());
  EXPECT_GT(homed_checked, 0);
  // The two rigs move differently (seeds 1 and 7), so the truth check above
  // tells their angles apart.
  EXPECT_GT(truths_differ, 0);
}
