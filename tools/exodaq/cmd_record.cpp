// exodaq record: the lab's recorder. Records the LCM traffic of a group into
// the standard LCM log format (lcm-logger's: lcm-logplayer, lcm-logger's
// readers and every exodaq tool read it) and accounts for every cycle of
// every daemon run it heard (docs/replay.md, "Recording").
//   exodaq record -o FILE.lcm [-c CONFIG] [-p PREFIX] [-u URL] [--channels RE]
//                 [--duration S] [--split-mb N | --split-s S] [--keep N]
//                 [--priority P] [--catch-up-s S] [--rcvbuf BYTES]
//                 [--memory-mb M] [--summary FILE.json]
// A thread of its own (SCHED_FIFO with --priority) drains the socket into
// memory (record_receiver.hpp); this thread parses, writes and counts. At the
// end, on stderr and in the summary file (JSON): the files, each run's
// cycles recorded, those the daemon skipped (its status counters), those lost
// between the daemon and the recorder, and the datagrams the kernel dropped
// at the recorder's socket. Exit 0: nothing lost that reached or should have
// reached this host; 1: something was lost (or a write failed, or nothing
// arrived); 2: bad arguments.
#include <arpa/inet.h>
#include <regex.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "command.hpp"
#include "exodaq/common/clock_now.hpp"
#include "exodaq/common/files.hpp"
#include "exodaq/core/udpm_sender.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq/messages/run_mix.hpp"
#include "exodaq/messages/seq_account.hpp"
#include "exodaq/settings/service_config.hpp"
#include "json_out.hpp"
#include "live_rig.hpp"
#include "record_receiver.hpp"

namespace exodaq::tools {
namespace {

// The catch-up bound (docs/can-protocol.md, "Late loop"): a daemon following
// a free-running board publishes, after a stall, every sample the board took
// meanwhile, three messages each (joint_state_t, palm_pose_t,
// encoder_raw_t), 64 cycles a millisecond. The socket must hold that burst
// while the recorder is held off too: catch_up_s of cycles, each datagram
// charged by the kernel at its buffer's true size, at most a page for these
// messages (1280 bytes over loopback, measured; a page behind some NICs).
constexpr int kMessagesPerCycle = 3;
constexpr std::int64_t kDatagramCharge = 4096;
constexpr std::int64_t kDatagramMemory = 1024;  // what one held in memory takes, at most
// After a stop, how long the recorder waits for each run's status to cover
// the cycles it recorded (statuses come every 100 ms).
constexpr std::int64_t kDrainNs = 500'000'000;

std::atomic<bool> g_stop{false};
extern "C" void on_record_signal(int) {
  g_stop.store(true);
}

struct RecordOptions {
  LiveRig rig;
  std::string out;
  std::string channels;
  double duration = 0.0;
  double split_mb = 0.0;
  double split_s = 0.0;
  int keep = 0;
  int priority = 0;
  double catch_up_s = 2.0;
  std::int64_t rcvbuf = 0;
  int memory_mb = 512;
  std::string summary;
};

std::string mb(std::int64_t bytes) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f MB", static_cast<double>(bytes) / 1e6);
  return b;
}

// "run.lcm" -> {"run", ".lcm"}.
std::pair<std::string, std::string> stem_and_extension(const std::string& path) {
  const std::size_t slash = path.rfind('/');
  const std::size_t dot = path.rfind('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash + 2) || dot == 0) {
    return {path, ""};
  }
  return {path.substr(0, dot), path.substr(dot)};
}

// Channels to record: an extended regular expression matched whole, as LCM
// subscriptions match.
class ChannelFilter {
 public:
  explicit ChannelFilter(const std::string& pattern) : pattern_(pattern) {
    const std::string whole = "^(" + pattern + ")$";
    const int rc = regcomp(&re_, whole.c_str(), REG_EXTENDED | REG_NOSUB);
    if (rc != 0) {
      char what[200];
      regerror(rc, &re_, what, sizeof what);
      throw std::runtime_error("--channels '" + pattern + "': " + what);
    }
  }
  ~ChannelFilter() { regfree(&re_); }
  ChannelFilter(const ChannelFilter&) = delete;
  ChannelFilter& operator=(const ChannelFilter&) = delete;

  bool operator()(const std::string& channel) {
    const auto it = cache_.find(channel);
    if (it != cache_.end()) return it->second;
    const bool match = regexec(&re_, channel.c_str(), 0, nullptr, 0) == 0;
    if (cache_.size() < 10000) cache_.emplace(channel, match);
    return match;
  }

 private:
  std::string pattern_;
  regex_t re_{};
  std::unordered_map<std::string, bool> cache_;
};

// One daemon run heard on one prefix.
struct RunState {
  std::string prefix;
  std::int64_t run_id = 0;
  messages::RunAccount account;
  std::optional<status_t> last_status;
  bool stopped = false;  // its STOPPING status heard
  bool repeat_reported = false;
  // Whether every cycle recorded is covered by a status heard (or the run stopped).
  bool covered() const {
    if (stopped) return true;
    std::int64_t last = -1;
    for (const messages::Kind k :
         {messages::Kind::kJointState, messages::Kind::kPalmPose, messages::Kind::kEncoderRaw}) {
      last = std::max(last, account.last_seq(k));
    }
    return last < 0 || (last_status && last_status->seq >= last);
  }
};

struct FileInfo {
  std::string path;
  std::int64_t events = 0;
  std::int64_t bytes = 0;
  bool removed = false;  // rotated away (--keep)
};

// LCM's UDP transport: LC02 datagrams, LC03 fragments reassembled (one
// message in flight per sender, as LCM keeps it).
struct Sender {
  std::uint32_t last_seqno = 0;
  bool have_seqno = false;
  std::uint32_t frag_seqno = 0;
  std::string frag_channel;
  std::vector<std::uint8_t> frag_data;
  int frags_expected = 0;
  int frags_got = 0;
  bool frag_open = false;
};

class Recording {
 public:
  Recording(const RecordOptions& o, const std::string& pattern)
      : o_(o), filter_(pattern), split_(o.split_mb > 0 || o.split_s > 0) {
    const auto [stem, ext] = stem_and_extension(o.out);
    stem_ = stem;
    ext_ = ext;
    open_next(0);
  }

  void on_datagram(const record::Datagram& d);
  // Hands what was written to the kernel; false after a write error.
  bool flush();
  void close();
  bool all_covered() const {
    for (const auto& [key, r] : runs_) {
      if (!r.covered()) return false;
    }
    return true;
  }

  std::string write_error;
  std::vector<FileInfo> files;
  std::int64_t events = 0;
  std::int64_t not_lcm = 0;         // datagrams that are not LCM's
  std::int64_t incomplete = 0;      // fragmented messages never completed
  std::int64_t sender_missing = 0;  // messages missing from their senders' numbering
  std::int64_t filtered = 0;        // messages on channels not recorded
  std::int64_t first_ns = 0;
  std::int64_t last_ns = 0;
  std::map<std::pair<std::string, std::int64_t>, RunState> runs_;

 private:
  void on_message(const std::string& channel, const std::uint8_t* data, std::size_t size,
                  std::int64_t recv_ns);
  void account(const std::string& channel, const std::uint8_t* data, std::size_t size);
  void open_next(int index);
  void note_seqno(Sender& s, std::uint32_t seqno);

  const RecordOptions& o_;
  ChannelFilter filter_;
  bool split_;
  std::string stem_;
  std::string ext_;
  int index_ = 0;
  std::unique_ptr<messages::LogAppender> log_;
  std::int64_t file_start_ns_ = 0;
  std::map<std::uint64_t, Sender> senders_;
  messages::RunMixDetector mix_;
  std::string channel_;
};

void Recording::open_next(int index) {
  for (;; ++index) {
    std::string path = o_.out;
    if (split_) {
      char n[24];
      std::snprintf(n, sizeof n, ".%03d", index);
      path = stem_ + n + ext_;
    }
    try {
      log_ = std::make_unique<messages::LogAppender>(path);
    } catch (const messages::LogError& e) {
      // A part name taken by an earlier recording: the next number (the first
      // part was checked before recording started).
      if (split_ && index > 0 && access(path.c_str(), F_OK) == 0) continue;
      throw;
    }
    files.push_back({path, 0, 0, false});
    index_ = index;
    file_start_ns_ = 0;
    break;
  }
  if (o_.keep > 0) {
    std::int64_t kept = 0;
    for (auto it = files.rbegin(); it != files.rend(); ++it) {
      if (it->removed) continue;
      if (++kept > o_.keep) {
        ::unlink(it->path.c_str());
        it->removed = true;
      }
    }
  }
}

void Recording::note_seqno(Sender& s, std::uint32_t seqno) {
  if (s.have_seqno) {
    const std::uint32_t gap = seqno - s.last_seqno - 1;  // mod 2^32
    if (seqno != s.last_seqno && gap < (1U << 31)) sender_missing += gap;
  }
  s.last_seqno = seqno;
  s.have_seqno = true;
}

void Recording::on_datagram(const record::Datagram& d) {
  const auto be32 = [](const std::uint8_t* p) {
    return static_cast<std::uint32_t>(p[0]) << 24 | static_cast<std::uint32_t>(p[1]) << 16 |
           static_cast<std::uint32_t>(p[2]) << 8 | p[3];
  };
  if (d.size < 8) {
    ++not_lcm;
    return;
  }
  const std::uint32_t magic = be32(d.data);
  const std::uint32_t seqno = be32(d.data + 4);
  Sender& s = senders_[static_cast<std::uint64_t>(d.source_ip) << 16 | d.source_port];
  if (magic == core::kLcmMagicShort) {
    const auto* name = reinterpret_cast<const char*>(d.data + 8);
    const std::size_t max = std::min<std::size_t>(d.size - 8, core::kLcmMaxChannelLength + 1);
    const std::size_t len = strnlen(name, max);
    if (len == max || len == 0) {
      ++not_lcm;
      return;
    }
    note_seqno(s, seqno);
    channel_.assign(name, len);
    on_message(channel_, d.data + 8 + len + 1, d.size - 8 - len - 1, d.recv_ns);
    return;
  }
  if (magic != core::kLcmMagicLong || d.size < 20) {
    ++not_lcm;
    return;
  }
  const std::uint32_t total = be32(d.data + 8);
  const std::uint32_t offset = be32(d.data + 12);
  const int number = d.data[16] << 8 | d.data[17];
  const int count = d.data[18] << 8 | d.data[19];
  const std::uint8_t* payload = d.data + 20;
  std::size_t payload_size = d.size - 20;
  if (number == 0) {
    if (s.frag_open) ++incomplete;
    const auto* name = reinterpret_cast<const char*>(payload);
    const std::size_t max = std::min<std::size_t>(payload_size, core::kLcmMaxChannelLength + 1);
    const std::size_t len = strnlen(name, max);
    if (len == max || len == 0 || total > (1U << 26) || count == 0) {
      ++not_lcm;
      s.frag_open = false;
      return;
    }
    note_seqno(s, seqno);
    s.frag_open = true;
    s.frag_seqno = seqno;
    s.frag_channel.assign(name, len);
    s.frag_data.assign(total, 0);
    s.frags_expected = count;
    s.frags_got = 0;
    payload += len + 1;
    payload_size -= len + 1;
  } else if (!s.frag_open || s.frag_seqno != seqno) {
    return;  // its first fragment was lost: counted with the sender's numbering
  }
  if (offset > s.frag_data.size() || payload_size > s.frag_data.size() - offset) {
    ++not_lcm;
    s.frag_open = false;
    return;
  }
  std::copy_n(payload, payload_size, s.frag_data.begin() + offset);
  if (++s.frags_got == s.frags_expected) {
    s.frag_open = false;
    on_message(s.frag_channel, s.frag_data.data(), s.frag_data.size(), d.recv_ns);
  }
}

void Recording::on_message(const std::string& channel, const std::uint8_t* data, std::size_t size,
                           std::int64_t recv_ns) {
  if (!filter_(channel)) {
    ++filtered;
    return;
  }
  if (first_ns == 0) first_ns = recv_ns;
  last_ns = recv_ns;
  if (!write_error.empty()) return;
  try {
    if (file_start_ns_ == 0) file_start_ns_ = recv_ns;
    const bool full = o_.split_mb > 0 && static_cast<double>(log_->bytes()) >= o_.split_mb * 1e6;
    const bool old =
        o_.split_s > 0 && static_cast<double>(recv_ns - file_start_ns_) >= o_.split_s * 1e9;
    if (split_ && log_->events() > 0 && (full || old)) {
      files.back().events = log_->events();
      files.back().bytes = log_->bytes();
      log_->close();
      open_next(index_ + 1);
      file_start_ns_ = recv_ns;
    }
    log_->write(channel, recv_ns / 1000, data, size);
    ++events;
  } catch (const messages::LogError& e) {
    write_error = e.what();
  }
  account(channel, data, size);
}

// The cycles of each exodaq run: per-cycle seq and the daemon's counters.
void Recording::account(const std::string& channel, const std::uint8_t* data, std::size_t size) {
  const auto parts = messages::split_channel(channel);
  if (!parts) return;
  const auto ks = messages::peek_stamp(data, size);
  if (!ks || ks->kind != parts->kind || ks->stamp.utime == 0) return;  // start-up messages: 0
  const bool per_cycle = messages::is_per_cycle(ks->kind);
  if (!per_cycle && ks->kind != messages::Kind::kStatus) return;
  if (const auto mix = mix_.observe(parts->prefix, ks->stamp.run_id)) {
    print_error("WARNING: " + messages::describe(*mix));
  }
  RunState& r = runs_[{parts->prefix, ks->stamp.run_id}];
  r.prefix = parts->prefix;
  r.run_id = ks->stamp.run_id;
  if (per_cycle) {
    if (r.account.add(ks->kind, ks->stamp.seq) == messages::SeqStep::kRepeat &&
        !r.repeat_reported) {
      r.repeat_reported = true;
      print_error("WARNING: run " + messages::run_id_text(r.run_id) + " on prefix '" + r.prefix +
                  "': seq " + std::to_string(ks->stamp.seq) + " of " + channel +
                  " is not new (last " + std::to_string(r.account.last_seq(ks->kind)) +
                  "): a second stream with this run id (replay --live of a live run?); counted "
                  "as repeated, recorded as received");
    }
    return;
  }
  status_t st;
  if (!messages::decode_into(st, data, size)) return;
  r.account.add_status(messages::daemon_counts(st));
  if (!r.last_status || st.seq >= r.last_status->seq) r.last_status = st;
  if (st.state == status_t::STATE_STOPPING) r.stopped = true;
}

bool Recording::flush() {
  if (!write_error.empty()) return false;
  try {
    log_->flush();
  } catch (const messages::LogError& e) {
    write_error = e.what();
  }
  return write_error.empty();
}

void Recording::close() {
  if (!log_) return;
  files.back().events = log_->events();
  files.back().bytes = log_->bytes();
  try {
    log_->close();
  } catch (const messages::LogError& e) {
    if (write_error.empty()) write_error = e.what();
  }
  if (files.back().events == 0 && write_error.empty()) {  // nothing recorded into it
    ::unlink(files.back().path.c_str());
    files.back().removed = true;
  }
  log_.reset();
}

// The loss counts that each stream's tally and the summary's totals both
// give, under the same keys (docs/replay.md "Recording").
struct Loss {
  std::int64_t missing = 0;
  std::int64_t skipped = 0;
  std::int64_t failed = 0;
  std::int64_t lost = 0;
  std::int64_t repeated = 0;
};

JsonObject& add_loss(JsonObject& j, const Loss& l) {
  return j.add("missing", std::to_string(l.missing))
      .add("skipped_by_daemon", std::to_string(l.skipped))
      .add("daemon_publish_failures", std::to_string(l.failed))
      .add("lost", std::to_string(l.lost))
      .add("repeated", std::to_string(l.repeated));
}

// Totals over every run's per-cycle streams: cycles and holes from
// joint_state_t, losses and repeats from all three.
struct Totals {
  std::int64_t cycles = 0;
  Loss loss;
};

JsonObject tally_json(const messages::SeqTally& t) {
  JsonObject j;
  j.add("received", std::to_string(t.received))
      .add("first_seq", std::to_string(t.first))
      .add("last_seq", std::to_string(t.last));
  add_loss(j, {t.missing, t.unpublished, t.failed, t.lost, t.repeated})
      .add("lost_after_last_status", std::to_string(t.unconfirmed))
      .add("out_of_order", std::to_string(t.late));
  return j;
}

struct Setup {
  std::string url;
  std::string pattern;
  core::UdpmAddress address;
  double rate_hz = 1000.0;
  std::int64_t needed = 0;  // socket buffer for the catch-up bound
  std::string summary;
};

Setup prepare(RecordOptions& o) {
  Setup s;
  double rate = 1000.0;
  if (!o.rig.config.empty()) rate = settings::load_service_config(o.rig.config).loop.rate_hz;
  resolve_live_rig(o.rig);
  s.url = o.rig.url;
  s.rate_hz = rate;
  const auto address = core::parse_udpm_url(s.url);
  if (!address) {
    throw std::runtime_error("--url '" + s.url +
                             "': exodaq record takes a udpm:// URL (udpm://GROUP:PORT?ttl=N)");
  }
  s.address = *address;
  s.pattern = !o.channels.empty() ? o.channels
                                  : (o.rig.prefix_given || !o.rig.prefix.empty()
                                         ? messages::regex_escape(o.rig.prefix) + ".*"
                                         : std::string(".*"));
  const auto cycles = static_cast<std::int64_t>(std::ceil(o.catch_up_s * rate));
  s.needed = o.rcvbuf > 0 ? o.rcvbuf : cycles * kMessagesPerCycle * kDatagramCharge;
  const auto [stem, ext] = stem_and_extension(o.out);
  s.summary = o.summary.empty() ? stem + ".summary.json" : o.summary;
  files::OutputOptions oo;
  files::check_output(s.summary, oo);
  if (access(s.summary.c_str(), F_OK) == 0) {
    throw files::FileError(s.summary, "exists (name another with --summary)");
  }
  return s;
}

void install_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_record_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGHUP, &sa, nullptr);
}

// Receives and writes until a signal, --duration or a write error, then until
// every run's cycles are covered by a status (at most kDrainNs more).
void record_loop(const RecordOptions& o, record::Receiver& rx, Recording& rec) {
  const std::int64_t start = mono_now_ns();
  const std::int64_t end = o.duration > 0 ? start + static_cast<std::int64_t>(o.duration * 1e9) : 0;
  std::int64_t stop_at = 0;  // when stopping began
  const auto process = [&](std::unique_ptr<record::Block> b) {
    b->for_each([&](const record::Datagram& d) { rec.on_datagram(d); });
    rx.give_back(std::move(b));
  };
  for (;;) {
    const std::int64_t now = mono_now_ns();
    if (stop_at == 0 && (g_stop.load() || (end != 0 && now >= end) || !rec.write_error.empty())) {
      stop_at = now;
    }
    if (stop_at != 0 &&
        (rec.all_covered() || now - stop_at >= kDrainNs || !rec.write_error.empty())) {
      break;
    }
    if (auto b = rx.take(50)) {
      process(std::move(b));
      while (auto more = rx.take(0)) process(std::move(more));
      rec.flush();
    }
  }
  rx.stop();
  while (auto b = rx.take(0)) process(std::move(b));
  rec.close();
}

int report(const RecordOptions& o, const Setup& s, const record::Receiver& rx,
           const Recording& rec) {
  const record::ReceiverStats st = rx.stats();
  Totals total;
  std::vector<JsonObject> runs;
  std::vector<std::string> lines;
  for (const auto& [key, r] : rec.runs_) {
    const messages::SeqTally joints = r.account.tally(messages::Kind::kJointState);
    const messages::SeqTally palms = r.account.tally(messages::Kind::kPalmPose);
    const messages::SeqTally raws = r.account.tally(messages::Kind::kEncoderRaw);
    total.cycles += joints.received;
    total.loss.missing += joints.missing;
    total.loss.skipped += joints.unpublished;
    total.loss.failed += joints.failed;
    for (const auto* t : {&joints, &palms, &raws}) {
      total.loss.lost += t->lost;
      total.loss.repeated += t->repeated;
    }
    JsonObject j;
    j.add("prefix", json_string(r.prefix))
        .add("run_id", json_string(messages::run_id_text(r.run_id)));
    j.add("joint_state", tally_json(joints).text(6))
        .add("palm_pose", tally_json(palms).text(6))
        .add("encoder_raw", tally_json(raws).text(6));
    if (r.last_status) {
      const status_t& ls = *r.last_status;
      JsonObject d;
      d.add("seq", std::to_string(ls.seq))
          .add("cycles", std::to_string(ls.cycles))
          .add("overruns", std::to_string(ls.overruns))
          .add("unpublished_seq", std::to_string(messages::daemon_counts(ls).unpublished))
          .add("publish_failures", std::to_string(ls.publish_failures))
          .add("stopped", json_bool(r.stopped));
      j.add("daemon_last_status", d.text(6));
    } else {
      j.add("daemon_last_status", "null");
    }
    runs.push_back(j);
    std::string line = "run " + messages::run_id_text(r.run_id) + " (prefix '" + r.prefix +
                       "'): " + messages::describe(joints);
    for (const auto& [name, t] :
         {std::pair<const char*, const messages::SeqTally*>{"palm_pose", &palms},
          {"encoder_raw", &raws}}) {
      if (t->received > 0 && (t->lost > 0 || t->repeated > 0)) {
        line += "; " + std::string(name) + ": " + messages::describe(*t);
      }
    }
    if (r.last_status) {
      line += "; the daemon: " + std::to_string(r.last_status->cycles) + " cycles published, " +
              std::to_string(r.last_status->overruns) + " overruns" +
              (r.stopped ? ", stopped" : ", still running");
    } else if (joints.received > 0) {
      line += "; no status heard: the daemon's share of any hole is unknown";
    }
    lines.push_back(line);
  }
  const std::int64_t recorder_lost = st.kernel_drops + st.memory_drops;
  const bool complete = total.loss.lost == 0 && recorder_lost == 0 && rec.incomplete == 0 &&
                        rec.write_error.empty() && rec.events > 0;

  std::vector<JsonObject> files;
  for (const FileInfo& f : rec.files) {
    JsonObject j;
    j.add("path", json_string(f.path))
        .add("events", std::to_string(f.events))
        .add("bytes", std::to_string(f.bytes))
        .add("removed", json_bool(f.removed));
    files.push_back(j);
  }
  JsonObject buffer;
  buffer.add("needed", std::to_string(s.needed))
      .add("granted", std::to_string(rx.rcvbuf_granted()))
      .add("forced", json_bool(rx.rcvbuf_forced()))
      .add("peak_queued", std::to_string(st.peak_queued))
      .add("catch_up_s", json_number(o.catch_up_s))
      .add("rate_hz", json_number(s.rate_hz));
  JsonObject j;
  j.add("complete", json_bool(complete))
      .add("url", json_string(s.url))
      .add("channels", json_string(s.pattern))
      .add("events", std::to_string(rec.events))
      .add("first_utime", std::to_string(rec.first_ns / 1000))
      .add("last_utime", std::to_string(rec.last_ns / 1000))
      .add("cycles", std::to_string(total.cycles));
  add_loss(j, total.loss)
      .add("datagrams", std::to_string(st.datagrams))
      .add("kernel_drops", std::to_string(st.kernel_drops))
      .add("memory_drops", std::to_string(st.memory_drops))
      .add("incomplete_fragmented", std::to_string(rec.incomplete))
      .add("not_lcm", std::to_string(rec.not_lcm + st.truncated))
      .add("sender_missing", std::to_string(rec.sender_missing))
      .add("receive_buffer", buffer.text(2))
      .add("peak_memory", std::to_string(st.peak_memory))
      .add("receive_thread", json_string(rx.priority_report()))
      .add("files", json_objects(files, 2))
      .add("runs", json_objects(runs, 2));
  if (!rec.write_error.empty()) j.add("write_error", json_string(rec.write_error));
  int rc = complete ? kExitOk : kExitFailure;
  try {
    files::write_output(s.summary, j.text() + "\n");
  } catch (const files::FileError& e) {
    print_error(e.what());
    rc = kExitFailure;
  }

  std::int64_t kept = 0;
  std::string names;
  for (const FileInfo& f : rec.files) {
    if (f.removed) continue;
    ++kept;
    names += (names.empty() ? "" : ", ") + f.path;
  }
  print_note(std::to_string(rec.events) + " events in " + std::to_string(kept) +
             " file(s): " + (names.empty() ? std::string("none") : names));
  for (const auto& l : lines) print_note(l);
  print_note("receive buffer " + mb(rx.rcvbuf_granted()) + " (" + mb(s.needed) +
             (o.rcvbuf > 0 ? std::string(" asked with --rcvbuf")
                           : " for " + json_number(o.catch_up_s) + " s of catch-up") +
             "), peak " + mb(st.peak_queued) + " queued; receive thread " + rx.priority_report() +
             "; " + std::to_string(rec.sender_missing) +
             " LCM messages missing from their senders' numbering");
  print_note("summary: " + s.summary);
  if (!rec.write_error.empty()) print_error(rec.write_error);
  if (rec.events == 0) {
    print_error("nothing received on " + s.url + " (channels '" + s.pattern +
                "'): is the daemon running, with this lcm.url?");
  }
  if (!complete && rec.events > 0) {
    print_error("INCOMPLETE: " + std::to_string(total.loss.lost) +
                " messages of cycles the daemon published lost on the way, " +
                std::to_string(st.kernel_drops) +
                " datagrams dropped by the kernel at the "
                "recorder's socket, " +
                std::to_string(st.memory_drops) + " dropped by the recorder (memory full), " +
                std::to_string(rec.incomplete) + " fragmented messages incomplete");
  }
  return rc;
}

int run_record(RecordOptions o) {
  if (o.split_mb > 0 && o.split_s > 0) {
    print_error("--split-mb and --split-s exclude each other");
    return kExitUsage;
  }
  if (o.keep > 0 && o.split_mb <= 0 && o.split_s <= 0) {
    print_error("--keep goes with --split-mb or --split-s");
    return kExitUsage;
  }
  const Setup s = prepare(o);
  Recording rec(o, s.pattern);  // creates the first file (never over an existing one)
  record::ReceiverOptions ro;
  ro.address = s.address;
  ro.url = s.url;
  ro.rcvbuf_bytes = s.needed;
  ro.priority = o.priority;
  ro.initial_bytes = static_cast<std::size_t>(std::ceil(o.catch_up_s * s.rate_hz) *
                                              kMessagesPerCycle * kDatagramMemory);
  ro.memory_bytes = static_cast<std::size_t>(o.memory_mb) << 20;
  std::unique_ptr<record::Receiver> rx;
  try {
    rx = std::make_unique<record::Receiver>(ro);
  } catch (...) {
    rec.close();
    throw;
  }
  if (rx->rcvbuf_granted() < s.needed) {
    print_error("WARNING: the kernel capped the receive buffer at " + mb(rx->rcvbuf_granted()) +
                " of the " + mb(s.needed) + " a catch-up of " + json_number(o.catch_up_s) +
                " s needs (net.core.rmem_max; SO_RCVBUFFORCE needs CAP_NET_ADMIN): raise "
                "net.core.rmem_max (docs/operations.md) or run as root");
  }
  install_handlers();
  rx->start();
  if (o.priority > 0 && rx->priority_report().find("refused") != std::string::npos) {
    print_error("WARNING: receive thread " + rx->priority_report());
  }
  print_note("recording " + s.url + " channels '" + s.pattern + "' -> " + rec.files.back().path +
             " (summary " + s.summary + "); Ctrl-C ends");
  record_loop(o, *rx, rec);
  return report(o, s, *rx, rec);
}

std::function<int()> setup_record(CLI::App& app) {
  auto o = std::make_shared<RecordOptions>();
  app.add_option("-o,--out", o->out,
                 "LCM log to write (never over an existing file); with --split-*: "
                 "NAME.000.EXT, NAME.001.EXT, ...")
      ->required();
  add_live_rig_options(app, o->rig);
  app.add_option("--channels", o->channels,
                 "channels to record, an extended regular expression matched whole (default: "
                 "every channel; with --prefix, that rig's)");
  app.add_option("--duration,-d", o->duration, "stop after S seconds (0: at Ctrl-C or SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--split-mb", o->split_mb, "start a new file after N MB")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--split-s", o->split_s, "start a new file after S seconds")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--keep", o->keep, "with --split-*: keep only the newest N files (rotation)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--priority", o->priority,
                 "SCHED_FIFO priority of the receive thread (1-99; 0: none; needs root or "
                 "CAP_SYS_NICE)")
      ->check(CLI::Range(0, 99));
  app.add_option("--catch-up-s", o->catch_up_s,
                 "the longest daemon stall whose catch-up burst the socket buffer must hold "
                 "(s of cycles)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--rcvbuf", o->rcvbuf, "socket receive buffer in bytes (instead of the computed)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--memory-mb", o->memory_mb,
                 "most memory held for the writer before datagrams are dropped (and counted)")
      ->capture_default_str()
      ->check(CLI::Range(8, 1 << 20));
  app.add_option("--summary", o->summary,
                 "the summary file (JSON; default NAME.summary.json beside the log)");
  return [o] { return run_record(*o); };
}

}  // namespace
}  // namespace exodaq::tools

EXODAQ_REGISTER_COMMAND(record, "record",
                        "record LCM traffic to an LCM log (lcm-logger's format) and account for "
                        "every cycle: recorded, skipped by the daemon, lost",
                        ::exodaq::tools::setup_record);
