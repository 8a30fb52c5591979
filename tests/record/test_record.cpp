// exodaq record, echo, export, replay and the Python client with real
// processes (issue 25 items 1, 2, 5 and 10):
//  - RecordSeq: a publisher with known holes (exodaq_test_seq_publisher):
//    the recorder, echo and the Python client split them into the daemon's
//    skipped seq and the lost ones, and say that a seq repeated;
//  - RecordLive: exodaqd on the sim recorded by exodaq record, beside the
//    real lcm-logger: the recorder's account against the daemon's own
//    counters; the log read by LCM's own reader and by the real
//    lcm-logplayer; split files and rotation; the issue's reproductions on
//    that recording (a damaged length, a flipped run id, an absurd seq, a run
//    held twice, a cut log);
//  - LogDamage: 20 random byte corruptions in a synthesized recording
//    (exodaq_test_damage_check).
// Where a receiver may lose messages on a loaded machine (LCM's queue in
// echo, the Python client), its loss is measured and only what it has is
// compared; the recorder's own counts are checked against the daemon's.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "process.hpp"
#include "sim_daemon.hpp"

namespace exodaq::test {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// A UDP port of this test process's own: concurrent tests do not hear it.
int private_port(int offset) {
  return 9100 + static_cast<int>(getpid() % 400) * 4 + offset;
}

std::string private_url(int offset) {
  return "udpm://239.255.76.67:" + std::to_string(private_port(offset)) + "?ttl=0";
}

RunResult exodaq(const std::vector<std::string>& args, std::chrono::milliseconds timeout = 120s) {
  std::vector<std::string> argv{EXODAQ_TOOL};
  argv.insert(argv.end(), args.begin(), args.end());
  return run(argv, timeout);
}

// The integer value of `field` in the JSON object under `key` ("" : the top
// level, whose fields come before the nested ones); -1 when absent.
std::int64_t json_int(const std::string& json, const std::string& key, const std::string& field) {
  std::size_t at = 0;
  if (!key.empty()) {
    at = json.find("\"" + key + "\": {");
    if (at == std::string::npos) return -1;
  }
  const std::string f = "\"" + field + "\": ";
  at = json.find(f, at);
  if (at == std::string::npos) return -1;
  return std::stoll(json.substr(at + f.size()));
}

bool json_true(const std::string& json, const std::string& field) {
  return json.find("\"" + field + "\": true") != std::string::npos;
}

struct Event {
  std::string channel;
  std::vector<std::uint8_t> data;
  std::int64_t timestamp = 0;
};

std::vector<Event> read_events(const std::string& path) {
  std::vector<Event> out;
  messages::LogReader log(path);
  messages::LogEvent ev;
  while (log.next(ev)) {
    out.push_back({std::string(ev.channel), {ev.data, ev.data + ev.size}, ev.timestamp});
  }
  EXPECT_TRUE(log.damage().empty()) << log.damage_text();
  return out;
}

// The same log through LCM's own reader (lcm_eventlog_read_next_event).
std::vector<Event> read_events_with_lcm(const std::string& path) {
  std::vector<Event> out;
  lcm::LogFile log(path, "r");
  EXPECT_TRUE(log.good()) << path;
  while (const lcm::LogEvent* ev = log.readNextEvent()) {
    const auto* d = static_cast<const std::uint8_t*>(ev->data);
    out.push_back({ev->channel, {d, d + ev->datalen}, ev->timestamp});
  }
  return out;
}

bool wait_for_file(const std::string& path, std::chrono::milliseconds timeout = 20s) {
  return wait_until([&] { return fs::exists(path); }, timeout);
}

// --- a stream with known holes ------------------------------------------------

TEST(RecordSeq, KnownHolesAreSplitIntoSkippedAndLostAndARepeatedSeqIsSaid) {
  const std::string dir = make_temp_dir("recseq");
  const std::string url = private_url(0);
  const std::string prefix = unique_prefix("seq");
  const std::string log = dir + "/seq.lcm";
  Process recorder({EXODAQ_TOOL, "record", "-o", log, "-u", url}, dir + "/rec.out",
                   dir + "/rec.err");
  Process echo({EXODAQ_TOOL, "echo", "-u", url, "-p", prefix, "--csv", "--duration", "60"},
               dir + "/echo.out", dir + "/echo.err");
  Process python({EXODAQ_PYTHON, std::string(EXODAQ_SOURCE_DIR) + "/tests/record/python_account.py",
                  url, prefix, dir + "/py.ready"},
                 dir + "/py.out", dir + "/py.err", {{"PYTHONPATH", EXODAQ_PYTHON_DIR}});
  ASSERT_TRUE(wait_for_file(log)) << read_file(dir + "/rec.err");
  ASSERT_TRUE(wait_for_file(dir + "/py.ready")) << read_file(dir + "/py.err");
  std::this_thread::sleep_for(500ms);  // echo's LCM subscription
  const RunResult pub = run({EXODAQ_SEQ_PUBLISHER, url, prefix});
  ASSERT_EQ(pub.exit_code, 0) << pub.err;
  std::this_thread::sleep_for(300ms);
  recorder.signal(SIGINT);
  echo.signal(SIGINT);
  const auto rec_code = recorder.wait(20s);
  const auto echo_code = echo.wait(20s);
  const auto py_code = python.wait(40s);

  // The recorder: its own socket, 24 MB of buffer; exact unless the kernel
  // dropped something (then it says so and those count as lost).
  const std::string summary = read_file(dir + "/seq.summary.json");
  const std::string rec_err = read_file(dir + "/rec.err");
  ASSERT_FALSE(summary.empty()) << rec_err;
  const std::int64_t drops = json_int(summary, "", "kernel_drops");
  EXPECT_EQ(rec_code, 1) << rec_err;  // 3 cycles lost: incomplete
  EXPECT_FALSE(json_true(summary, "complete"));
  for (const char* kind : {"joint_state", "palm_pose", "encoder_raw"}) {
    EXPECT_EQ(json_int(summary, kind, "skipped_by_daemon"), 4) << kind << "\n" << summary;
    EXPECT_EQ(json_int(summary, kind, "first_seq"), 0) << kind;
    EXPECT_EQ(json_int(summary, kind, "last_seq"), 599) << kind;
    if (drops == 0) {
      EXPECT_EQ(json_int(summary, kind, "received"), 593) << kind;
      EXPECT_EQ(json_int(summary, kind, "lost"), 3) << kind;
      EXPECT_EQ(json_int(summary, kind, "repeated"), 5) << kind;
    }
  }
  if (drops == 0) {
    EXPECT_EQ(json_int(summary, "", "lost"), 9);
  }
  EXPECT_NE(rec_err.find("WARNING: run 0000000000005eed on prefix '" + prefix + "': seq 10 of " +
                         prefix + "EXO_"),
            std::string::npos)
      << rec_err;
  EXPECT_NE(rec_err.find("): 593 cycles (seq 0..599), 7 missing in 4 holes: 4 skipped by the "
                         "daemon, 3 lost, 5 with a seq not new"),
            std::string::npos)
      << rec_err;
  EXPECT_NE(rec_err.find("exodaq record: INCOMPLETE: 9 messages of cycles the daemon published"),
            std::string::npos)
      << rec_err;
  // The log holds what was received, in lcm-logger's format.
  std::int64_t joints = 0;
  for (const auto& e : read_events(log)) joints += e.channel == prefix + "EXO_JOINT_STATE";
  EXPECT_EQ(joints, json_int(summary, "joint_state", "received") +
                        json_int(summary, "joint_state", "repeated"));

  // echo (through LCM, which may drop behind a busy CPU): the daemon's 4
  // skipped seq are its own whatever echo lost; a repeated seq it received
  // is said.
  const std::string echo_err = read_file(dir + "/echo.err");
  EXPECT_EQ(echo_code, 0) << echo_err;
  std::vector<std::int64_t> echo_seqs;
  {
    std::istringstream in(read_file(dir + "/echo.out"));
    std::string line;
    std::getline(in, line);  // header
    while (std::getline(in, line)) {
      std::size_t a = line.find(',');
      a = line.find(',', a + 1);
      echo_seqs.push_back(std::stoll(line.substr(a + 1)));
    }
  }
  ASSERT_FALSE(echo_seqs.empty()) << echo_err;
  std::int64_t echo_repeats = 0;
  std::int64_t newest = -1;
  for (const std::int64_t s : echo_seqs) {
    echo_repeats += s <= newest;
    newest = std::max(newest, s);
  }
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      echo_err, m,
      std::regex(
          R"(run 0000000000005eed: (\d+) cycles \(seq \d+\.\.599\), (\d+) missing in \d+ holes?: (\d+) skipped by the daemon, (\d+) lost)")))
      << echo_err;
  EXPECT_EQ(std::stoll(m[3]), 4) << echo_err;
  EXPECT_GE(std::stoll(m[4]), 3) << echo_err;
  EXPECT_EQ(std::stoll(m[1]) + std::stoll(m[2]), 600 - echo_seqs.front()) << echo_err;
  if (echo_repeats > 0) {
    EXPECT_NE(echo_err.find("interleaved or repeated seq of one run id"), std::string::npos)
        << echo_err;
  }

  // The Python client (its own socket, 2 MB).
  const std::string py = read_file(dir + "/py.out");
  ASSERT_EQ(py_code, 0) << py << read_file(dir + "/py.err");
  const auto py_int = [&](const std::string& f) { return json_int(py, "", f); };
  EXPECT_EQ(py_int("skipped"), 4) << py;
  EXPECT_GE(py_int("lost"), 3) << py;
  EXPECT_EQ(py_int("pending"), 0) << py;
  EXPECT_EQ(py_int("status_returned"), 0) << py;
  EXPECT_EQ(py_int("received") - py_int("repeated") + py_int("lost") + py_int("skipped"), 600)
      << py;
  if (py_int("repeated") > 0) {
    EXPECT_NE(read_file(dir + "/py.err").find("interleaved or repeated seq of one run id"),
              std::string::npos);
  }
  std::printf("SEQ: recorder exit %d, %lld kernel drops; echo %zu rows (%s); python %s\n",
              rec_code.value_or(-1), static_cast<long long>(drops), echo_seqs.size(),
              std::string(m[0]).c_str(), py.substr(0, py.find(", \"seqs\"")).c_str());
}

TEST(RecordSeq, NothingReceivedIsSaidAndExitOneWithNoFileLeft) {
  const std::string dir = make_temp_dir("recnone");
  const std::string url = private_url(1);
  const RunResult echo = exodaq({"echo", "-o", dir + "/x.csv", "--duration", "2", "-u", url});
  EXPECT_EQ(echo.exit_code, 1) << echo.err;
  EXPECT_NE(
      echo.err.find("exodaq echo: nothing received on EXO_JOINT_STATE from " + url + " within 2 s"),
      std::string::npos)
      << echo.err;
  EXPECT_FALSE(fs::exists(dir + "/x.csv"));
  const RunResult rec = exodaq({"record", "-o", dir + "/n.lcm", "--duration", "1", "-u", url});
  EXPECT_EQ(rec.exit_code, 1) << rec.err;
  EXPECT_NE(rec.err.find("exodaq record: nothing received on " + url), std::string::npos)
      << rec.err;
  EXPECT_FALSE(fs::exists(dir + "/n.lcm"));
  EXPECT_TRUE(fs::exists(dir + "/n.summary.json"));
  // A recording is never written over a file.
  std::ofstream(dir + "/taken.lcm") << "x";
  const RunResult taken = exodaq({"record", "-o", dir + "/taken.lcm", "-u", url});
  EXPECT_EQ(taken.exit_code, 2) << taken.err;
  EXPECT_NE(taken.err.find("taken.lcm: exists"), std::string::npos) << taken.err;
  EXPECT_EQ(read_file(dir + "/taken.lcm"), "x");
}

// Without CAP_NET_ADMIN the buffer stops at net.core.rmem_max (the kernel
// doubles it), without CAP_SYS_NICE there is no SCHED_FIFO: both are said at
// start and in the summary.
TEST(RecordSeq, ACappedBufferAndARefusedPriorityAreSaid) {
  if (geteuid() != 0 || !fs::exists("/usr/bin/setpriv")) {
    GTEST_SKIP() << "needs root and setpriv to take the capabilities away";
  }
  const std::string dir = make_temp_dir("reccap");
  const std::int64_t rmem_max = std::stoll(read_file("/proc/sys/net/core/rmem_max"));
  if (2 * rmem_max >= 2000 * 3 * 4096) GTEST_SKIP() << "net.core.rmem_max holds the buffer";
  const RunResult r =
      run({"/usr/bin/setpriv", "--bounding-set", "-net_admin,-sys_nice", EXODAQ_TOOL, "record",
           "-o", dir + "/cap.lcm", "-u", private_url(1), "--duration", "0.3", "--priority", "5"});
  EXPECT_EQ(r.exit_code, 1) << r.err;  // nothing received
  char granted[32];
  std::snprintf(granted, sizeof granted, "%.1f MB", 2.0 * static_cast<double>(rmem_max) / 1e6);
  EXPECT_NE(r.err.find("exodaq record: WARNING: the kernel capped the receive buffer at " +
                       std::string(granted) + " of the 24.6 MB a catch-up of 2 s needs"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("exodaq record: WARNING: receive thread SCHED_FIFO 5 refused"),
            std::string::npos)
      << r.err;
  const std::string s = read_file(dir + "/cap.summary.json");
  EXPECT_EQ(json_int(s, "receive_buffer", "granted"), 2 * rmem_max) << s;
  EXPECT_NE(s.find("\"forced\": false"), std::string::npos) << s;
}

// --- the daemon, recorded ------------------------------------------------------

struct Live {
  std::string dir;
  std::string prefix;
  std::string config;
  std::string url;
  std::string log;  // exodaq record
  std::string summary;
  std::string rec_err;
  int rec_code = -1;
  std::string logger;     // lcm-logger, beside it
  std::string split_dir;  // exodaq record --split-s 1 --keep 2
  std::string split_summary;
  int split_code = -1;
  std::int64_t daemon_cycles = 0;  // its final status
};
Live* g_live = nullptr;

class RecordLive : public ::testing::Test {
 protected:
  // One recording for this suite and Reproduction (set up once, kept to the end).
  static void SetUpTestSuite() {
    if (g_live != nullptr) return;
    auto* live = new Live;
    live->dir = make_temp_dir("reclive");
    live->prefix = unique_prefix("rec");
    live->url = private_url(2);
    std::string text = sim_config_text(live->prefix);
    replace_once(text, "udpm://239.255.76.67:7667?ttl=0", live->url);
    live->config = write_config_text(live->dir, text);
    live->log = live->dir + "/live.lcm";
    live->summary = live->dir + "/live.summary.json";
    live->logger = live->dir + "/logger.lcm";
    live->split_dir = live->dir + "/split";
    fs::create_directories(live->split_dir);
    live->split_summary = live->split_dir + "/part.summary.json";
    std::optional<int> rec_code;
    std::optional<int> split_code;
    {
      Process recorder(
          {EXODAQ_TOOL, "record", "-o", live->log, "-c", live->config, "--priority", "10"},
          live->dir + "/rec.out", live->dir + "/rec.err");
      Process split({EXODAQ_TOOL, "record", "-o", live->split_dir + "/part.lcm", "-c", live->config,
                     "--split-s", "1", "--keep", "2"},
                    live->dir + "/split.out", live->dir + "/split.err");
      Process logger(
          lcm_logger_argv(live->url + "&recv_buf_size=4194304", live->prefix + ".*", live->logger),
          live->dir + "/logger.out", live->dir + "/logger.err");
      ASSERT_TRUE(wait_for_file(live->log)) << read_file(live->dir + "/rec.err");
      ASSERT_TRUE(wait_for_file(live->logger)) << "lcm-logger did not start";
      std::this_thread::sleep_for(300ms);
      const RunResult daemon = run({EXODAQD, "--config", live->config, "--duration", "4.5"}, 60s);
      ASSERT_EQ(daemon.exit_code, 0) << daemon.err;
      std::this_thread::sleep_for(300ms);
      recorder.signal(SIGINT);
      split.signal(SIGINT);
      logger.signal(SIGINT);
      rec_code = recorder.wait(20s);
      split_code = split.wait(20s);
      ASSERT_TRUE(logger.wait(10s).has_value());
    }
    live->rec_code = rec_code.value_or(-1);
    live->split_code = split_code.value_or(-1);
    live->rec_err = read_file(live->dir + "/rec.err");
    for (const auto& e : read_events(live->log)) {
      if (e.channel != live->prefix + "EXO_STATUS") continue;
      const auto st = decode<status_t>(e.data);
      if (st.state == status_t::STATE_STOPPING) live->daemon_cycles = st.cycles;
    }
    ASSERT_GT(live->daemon_cycles, 1000) << "no final status recorded";
    g_live = live;
  }
  void SetUp() override {
    if (g_live == nullptr) GTEST_SKIP() << "the live recording failed (see the first test)";
  }
};

// The recorder's account is the daemon's: every cycle it published is
// recorded or counted lost; the exit code says whether anything was lost.
TEST_F(RecordLive, TheSummaryAccountsForEveryCycleTheDaemonPublished) {
  const std::string s = read_file(g_live->summary);
  ASSERT_FALSE(s.empty()) << g_live->rec_err;
  const std::int64_t received = json_int(s, "joint_state", "received");
  const std::int64_t lost = json_int(s, "joint_state", "lost");
  const std::int64_t skipped = json_int(s, "joint_state", "skipped_by_daemon");
  EXPECT_EQ(json_int(s, "joint_state", "first_seq"), 0);
  EXPECT_EQ(json_int(s, "joint_state", "repeated"), 0);
  EXPECT_EQ(received + lost, g_live->daemon_cycles) << s;
  EXPECT_EQ(json_int(s, "daemon_last_status", "cycles"), g_live->daemon_cycles);
  if (lost == 0) {
    EXPECT_EQ(json_int(s, "joint_state", "last_seq"), json_int(s, "daemon_last_status", "seq"));
  }
  EXPECT_EQ(received + lost + skipped, json_int(s, "joint_state", "last_seq") + 1);
  EXPECT_TRUE(s.find("\"stopped\": true") != std::string::npos) << s;
  const std::int64_t recorder_lost =
      json_int(s, "", "lost") + json_int(s, "", "kernel_drops") + json_int(s, "", "memory_drops");
  EXPECT_EQ(g_live->rec_code, recorder_lost == 0 ? 0 : 1) << g_live->rec_err;
  EXPECT_EQ(json_true(s, "complete"), recorder_lost == 0);
  // The buffer asked for (2 s of catch-up: 2000 cycles x 3 datagrams x 4 KiB)
  // and granted: the test runs as root, which may force it.
  EXPECT_EQ(json_int(s, "receive_buffer", "needed"), 2000 * 3 * 4096);
  if (geteuid() == 0) {
    EXPECT_EQ(json_int(s, "receive_buffer", "granted"), 2000 * 3 * 4096);
  }
  std::printf(
      "LIVE: daemon %lld cycles; recorder %lld received, %lld skipped by the daemon, "
      "%lld lost, %lld kernel drops, exit %d\n",
      static_cast<long long>(g_live->daemon_cycles), static_cast<long long>(received),
      static_cast<long long>(skipped), static_cast<long long>(lost),
      static_cast<long long>(json_int(s, "", "kernel_drops")), g_live->rec_code);
}

// lcm-logger's format: LCM's own reader and the real lcm-logplayer read every
// event, byte for byte and in order.
TEST_F(RecordLive, LcmsOwnReaderAndLcmLogplayerReadTheRecording) {
  const auto ours = read_events(g_live->log);
  const auto lcms = read_events_with_lcm(g_live->log);
  ASSERT_EQ(ours.size(), lcms.size());
  for (std::size_t i = 0; i < ours.size(); ++i) {
    ASSERT_EQ(ours[i].channel, lcms[i].channel) << i;
    ASSERT_EQ(ours[i].data, lcms[i].data) << i;
    ASSERT_EQ(ours[i].timestamp, lcms[i].timestamp) << i;
  }
  // lcm-logplayer -v names each event it plays: channel and size, in order.
  const RunResult played =
      run({"lcm-logplayer", "-v", "-s", "1000", "--lcm-url=" + private_url(3), g_live->log}, 120s);
  ASSERT_EQ(played.exit_code, 0) << played.err;
  std::vector<std::pair<std::string, std::size_t>> listed;
  std::istringstream in(played.out);
  std::string line;
  const std::regex r(R"(Channel (\S+)\s+size (\d+))");
  while (std::getline(in, line)) {
    std::smatch m;
    if (std::regex_search(line, m, r)) listed.emplace_back(m[1], std::stoul(m[2]));
  }
  ASSERT_EQ(listed.size(), ours.size()) << played.out.substr(0, 400);
  for (std::size_t i = 0; i < ours.size(); ++i) {
    ASSERT_EQ(listed[i].first, ours[i].channel) << i;
    ASSERT_EQ(listed[i].second, ours[i].data.size()) << i;
  }
}

// The real lcm-logger beside it: each message lcm-logger recorded is in the
// recorder's log (compared where both have it); lcm-logger's loss reported.
TEST_F(RecordLive, EveryMessageLcmLoggerGotIsInTheRecording) {
  std::multiset<std::vector<std::uint8_t>> ours;
  std::int64_t our_joints = 0;
  for (const auto& e : read_events(g_live->log)) {
    if (e.channel.rfind(g_live->prefix, 0) != 0) continue;
    ours.insert(e.data);
    our_joints += e.channel == g_live->prefix + "EXO_JOINT_STATE";
  }
  const auto theirs = read_events_with_lcm(g_live->logger);
  ASSERT_FALSE(theirs.empty());
  std::int64_t missing = 0;
  std::int64_t their_joints = 0;
  for (const auto& e : theirs) {
    missing += ours.count(e.data) == 0;
    their_joints += e.channel == g_live->prefix + "EXO_JOINT_STATE";
  }
  const std::int64_t recorder_lost = json_int(read_file(g_live->summary), "", "lost");
  EXPECT_LE(missing, recorder_lost)
      << "lcm-logger got messages the recorder neither has nor counted lost";
  std::printf("LCM-LOGGER: %lld joint states of the daemon's %lld (recorder: %lld)\n",
              static_cast<long long>(their_joints), static_cast<long long>(g_live->daemon_cycles),
              static_cast<long long>(our_joints));
}

// --split-s 1 --keep 2: parts of a second each, the two newest kept, each a
// whole log; the summary lists them all.
TEST_F(RecordLive, SplitFilesRotateAndEachPartIsAWholeLog) {
  const std::string s = read_file(g_live->split_summary);
  ASSERT_FALSE(s.empty()) << read_file(g_live->dir + "/split.err");
  std::vector<std::string> kept;
  for (const auto& f : fs::directory_iterator(g_live->split_dir)) {
    if (f.path().extension() == ".lcm") kept.push_back(f.path().filename());
  }
  std::sort(kept.begin(), kept.end());
  ASSERT_EQ(kept.size(), 2u);
  const std::regex file(
      R"re("path": "([^"]+)",\s*"events": (\d+),\s*"bytes": \d+,\s*"removed": (true|false))re");
  std::int64_t parts = 0;
  std::int64_t events = 0;
  std::int64_t removed = 0;
  for (auto it = std::sregex_iterator(s.begin(), s.end(), file); it != std::sregex_iterator();
       ++it) {
    ++parts;
    events += std::stoll((*it)[2]);
    removed += (*it)[3] == "true";
    const std::string path = (*it)[1];
    EXPECT_EQ(fs::exists(path), (*it)[3] == "false") << path;
    if (fs::exists(path)) {
      EXPECT_EQ(static_cast<std::int64_t>(read_events(path).size()), std::stoll((*it)[2])) << path;
    }
  }
  EXPECT_GE(parts, 4) << s;  // 4.5 s of daemon at a second a part
  EXPECT_EQ(removed, parts - 2);
  EXPECT_EQ(events, json_int(s, "", "events"));
  EXPECT_EQ(kept.back(), "part." + std::string(parts - 1 < 10 ? "00" : "0") +
                             std::to_string(parts - 1) + ".lcm");
}

// --- the issue's reproductions on the recording --------------------------------

struct Located {
  std::int64_t offset = 0;
  std::int64_t data_at = 0;
  std::size_t size = 0;
  std::int64_t seq = 0;
};

// The joint_state_t events of the recording, in order.
std::vector<Located> joint_events(const std::string& path, const std::string& prefix) {
  std::vector<Located> out;
  messages::LogReader log(path);
  messages::LogEvent ev;
  while (log.next(ev)) {
    if (ev.channel != prefix + "EXO_JOINT_STATE") continue;
    const auto st = messages::peek_stamp(ev.data, ev.size);
    if (!st || st->stamp.utime == 0) continue;
    out.push_back({ev.offset, ev.offset + 28 + static_cast<std::int64_t>(ev.channel.size()),
                   ev.size, st->stamp.seq});
  }
  return out;
}

std::string bytes_of(const std::string& path) {
  return read_file(path);
}

void write_bytes(const std::string& path, const std::string& b) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << b;
}

std::int64_t csv_rows(const std::string& path) {
  std::ifstream in(path);
  std::int64_t n = -1;  // the header
  for (std::string line; std::getline(in, line);) ++n;
  return n;
}

void put_be32(std::string& b, std::int64_t at, std::uint32_t v) {
  for (int k = 0; k < 4; ++k)
    b[static_cast<std::size_t>(at + k)] = static_cast<char>(v >> (24 - 8 * k));
}

class Reproduction : public RecordLive {
 protected:
  void SetUp() override {
    RecordLive::SetUp();
    if (g_live == nullptr) return;
    reference_ = g_live->dir + "/reference.csv";
    if (!fs::exists(reference_)) {
      const RunResult r = exodaq({"export", g_live->log, "-o", reference_});
      ASSERT_EQ(r.exit_code, 0) << r.err;
    }
    rows_ = csv_rows(reference_);
    joints_ = joint_events(g_live->log, g_live->prefix);
    ASSERT_GT(joints_.size(), 1000u);
  }
  std::string reference_;
  std::int64_t rows_ = 0;
  std::vector<Located> joints_;
};

// One event's data length 345 -> 9,437,529 (within the file here: the
// length ends past the next event, not past the end) cost half the log; now
// that event's cycle.
TEST_F(Reproduction, ADamagedDataLengthCostsOneCycleExportAndReplaySaySo) {
  std::string b = bytes_of(g_live->log);
  const Located& j = joints_[joints_.size() / 3];
  const auto length = static_cast<std::uint32_t>(
      std::min<std::int64_t>(9'437'529, static_cast<std::int64_t>(b.size()) - j.data_at - 100));
  put_be32(b, j.offset + 24, length);
  const std::string damaged = g_live->dir + "/length.lcm";
  write_bytes(damaged, b);
  const std::string range = damaged + ", bytes " + std::to_string(j.offset) + "..";
  const RunResult ex = exodaq({"export", damaged, "-o", g_live->dir + "/length.csv"});
  EXPECT_EQ(ex.exit_code, 1) << ex.err;
  EXPECT_EQ(csv_rows(g_live->dir + "/length.csv"), rows_ - 1) << ex.err;
  EXPECT_NE(ex.err.find("exodaq export: " + range), std::string::npos) << ex.err;
  EXPECT_NE(ex.err.find("runs past the next event"), std::string::npos) << ex.err;
  EXPECT_NE(ex.err.find("; 1 event lost (after event "), std::string::npos) << ex.err;
  EXPECT_NE(ex.err.find("cycles lost with it: 1 (seq " + std::to_string(j.seq) + ".." +
                        std::to_string(j.seq) + ")"),
            std::string::npos)
      << ex.err;
  // The replay reads the raw channel: the damaged joint event costs it
  // nothing, but the damage is named and the exit code says so.
  const RunResult rp =
      exodaq({"replay", damaged, "-c", g_live->config, "-o", g_live->dir + "/length-replay.lcm"});
  EXPECT_EQ(rp.exit_code, 1) << rp.err;
  EXPECT_NE(rp.err.find("bytes " + std::to_string(j.offset) + ".."), std::string::npos) << rp.err;
  EXPECT_NE(rp.err.find("damaged or malformed input"), std::string::npos) << rp.err;
}

// A flipped run_id in one message: not "two daemons"; that message named and
// left out, every other row exported.
TEST_F(Reproduction, AFlippedRunIdIsNamedNotTwoDaemons) {
  std::string b = bytes_of(g_live->log);
  const Located& j = joints_[joints_.size() / 2];
  b[static_cast<std::size_t>(j.data_at + 8 + 24 + 3)] ^= 0x5a;  // a byte of run_id
  const std::string damaged = g_live->dir + "/runid.lcm";
  write_bytes(damaged, b);
  const RunResult ex = exodaq({"export", damaged, "-o", g_live->dir + "/runid.csv"});
  EXPECT_EQ(ex.exit_code, 1) << ex.err;
  EXPECT_EQ(ex.err.find("two runs interleaved"), std::string::npos) << ex.err;
  EXPECT_NE(ex.err.find("1 message(s) with a run id no run of the log has (a damaged run id)"),
            std::string::npos)
      << ex.err;
  EXPECT_NE(ex.err.find("(byte " + std::to_string(j.offset) + "): run id "), std::string::npos)
      << ex.err;
  EXPECT_EQ(csv_rows(g_live->dir + "/runid.csv"), rows_ - 1);
}

// An absurd seq, with --run-id: named and left out, not exported silently.
TEST_F(Reproduction, AnAbsurdSeqIsNamedAndLeftOut) {
  std::string b = bytes_of(g_live->log);
  const Located& j = joints_[joints_.size() / 4];
  b[static_cast<std::size_t>(j.data_at + 8 + 16)] ^= static_cast<char>(0xa8);  // seq's top byte
  const std::string damaged = g_live->dir + "/seq.lcm";
  write_bytes(damaged, b);
  const std::string run_id =
      read_file(g_live->summary).substr(read_file(g_live->summary).find("\"run_id\": \"") + 11, 16);
  const RunResult ex =
      exodaq({"export", damaged, "-o", g_live->dir + "/seq.csv", "--run-id", run_id});
  EXPECT_EQ(ex.exit_code, 1) << ex.err;
  EXPECT_NE(ex.err.find("1 message(s) with a seq out of line with their neighbours"),
            std::string::npos)
      << ex.err;
  EXPECT_NE(ex.err.find("joint_state_t seq -"), std::string::npos) << ex.err;
  EXPECT_EQ(csv_rows(g_live->dir + "/seq.csv"), rows_ - 1);
  const std::string csv = read_file(g_live->dir + "/seq.csv");
  EXPECT_EQ(csv.find(",-"), csv.find(",-"));  // no row with a negative seq column
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::size_t a = line.find(',');
    a = line.find(',', a + 1);
    ASSERT_NE(line[a + 1], '-') << line.substr(0, 80);
  }
}

// `cat a.lcm a.lcm`: the run held twice lost the last cycles into the join
// window with exit 0; now the repeats are named, exported once, exit 1. Two
// consecutive parts of one recording joined are one clean log.
TEST_F(Reproduction, ARunHeldTwiceIsNamedAndConsecutivePartsJoinCleanly) {
  const std::string twice = g_live->dir + "/twice.lcm";
  write_bytes(twice, bytes_of(g_live->log) + bytes_of(g_live->log));
  const RunResult ex = exodaq({"export", twice, "-o", g_live->dir + "/twice.csv"});
  EXPECT_EQ(ex.exit_code, 1) << ex.err;
  EXPECT_NE(ex.err.find("message(s) repeat seq numbers already read (the log holds this run "
                        "twice"),
            std::string::npos)
      << ex.err;
  EXPECT_EQ(read_file(g_live->dir + "/twice.csv"), read_file(reference_));

  // The split recording's kept parts, joined in order.
  std::vector<std::string> parts;
  for (const auto& f : fs::directory_iterator(g_live->split_dir)) {
    if (f.path().extension() == ".lcm") parts.push_back(f.path());
  }
  std::sort(parts.begin(), parts.end());
  ASSERT_EQ(parts.size(), 2u);
  const std::string joined = g_live->dir + "/joined.lcm";
  write_bytes(joined, bytes_of(parts[0]) + bytes_of(parts[1]));
  const RunResult a = exodaq({"export", parts[0], "-o", g_live->dir + "/p0.csv"});
  const RunResult b2 = exodaq({"export", parts[1], "-o", g_live->dir + "/p1.csv"});
  const RunResult j = exodaq({"export", joined, "-o", g_live->dir + "/joined.csv"});
  EXPECT_EQ(j.exit_code, 0) << j.err;
  // A cycle split across the two parts is one row of the joined log.
  EXPECT_GE(csv_rows(g_live->dir + "/joined.csv"),
            csv_rows(g_live->dir + "/p0.csv") + csv_rows(g_live->dir + "/p1.csv") - 1)
      << a.err << b2.err << j.err;
}

// A cut log: replay and export exit 1 and say where. The cut falls inside an
// event, after its 28-byte header (a cut inside a header is reported as
// "less than an event header": a place that depended on the recording's size).
TEST_F(Reproduction, ACutLogIsExitOne) {
  std::string b = bytes_of(g_live->log);
  const std::size_t event = b.find(std::string("\xED\xA1\xDA\x01", 4), b.size() * 2 / 3);
  ASSERT_NE(event, std::string::npos);
  b.resize(event + 28 + 10);
  const std::string cut = g_live->dir + "/cut.lcm";
  write_bytes(cut, b);
  const RunResult rp =
      exodaq({"replay", cut, "-c", g_live->config, "-o", g_live->dir + "/cut-replay.lcm"});
  EXPECT_EQ(rp.exit_code, 1) << rp.err;
  EXPECT_NE(rp.err.find("cut by the end of the file"), std::string::npos) << rp.err;
  const RunResult ex = exodaq({"export", cut, "-o", g_live->dir + "/cut.csv"});
  EXPECT_EQ(ex.exit_code, 1) << ex.err;
  EXPECT_NE(ex.err.find(cut + ", bytes "), std::string::npos) << ex.err;
}

// --- random damage -------------------------------------------------------------

TEST(LogDamage, TwentyRandomCorruptionsCostOnlyWhatTheyHit) {
  const std::string dir = make_temp_dir("damage");
  const std::string log = dir + "/long.lcm";
  const RunResult made = run({EXODAQ_MAKE_LOG, log, "20000"});
  ASSERT_EQ(made.exit_code, 0) << made.err;
  const std::string config = std::string(EXODAQ_SOURCE_DIR) + "/config/sim.yaml";
  for (const char* seed : {"1", "2", "3"}) {
    const RunResult r = run({EXODAQ_DAMAGE_CHECK, EXODAQ_TOOL, config, log, dir, "20", seed}, 300s);
    EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
    std::printf("%s", r.out.c_str());
  }
}

}  // namespace
}  // namespace exodaq::test
