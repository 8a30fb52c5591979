#include "exodaq/drivers/replay_source.hpp"

#include <lcm/lcm.h>
#include <stdio_ext.h>

#include <array>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <stdexcept>

#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"

namespace exodaq::drivers {

namespace {

constexpr std::string_view kRawBase = "EXO_ENCODER_RAW";
constexpr std::string_view kJointBase = "EXO_JOINT_STATE";
constexpr std::uint32_t kLcmLogMagic = 0xEDA1DA01U;
constexpr std::size_t kMaxStoredIssues = 1000;

// Bits the loop (not the source) adds to a live sample; the raw channel does
// not carry them, the recorded joint_state_t does.
constexpr std::uint32_t kLoopFlags =
    sample_flag::kLate | sample_flag::kClockStep | sample_flag::kClockUnsync;
constexpr std::int32_t kJointHeld = 64;  // joint_state_t::JOINT_HELD

bool ends_with(std::string_view s, std::string_view suffix) noexcept {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

struct EventLog {
  explicit EventLog(const std::string& path) : log(lcm_eventlog_create(path.c_str(), "r")) {
    if (log == nullptr) {
      throw std::runtime_error("replay: cannot open LCM log '" + path +
                               "': " + std::strerror(errno));
    }
    // One thread reads it: skip stdio's per-call locking (LCM reads field by field).
    __fsetlocking(log->f, FSETLOCKING_BYCALLER);
  }
  ~EventLog() { lcm_eventlog_destroy(log); }
  EventLog(const EventLog&) = delete;
  EventLog& operator=(const EventLog&) = delete;
  lcm_eventlog_t* log;
};

struct EventDeleter {
  void operator()(lcm_eventlog_event_t* e) const noexcept { lcm_eventlog_free_event(e); }
};
using EventPtr = std::unique_ptr<lcm_eventlog_event_t, EventDeleter>;

// span * k / d without overflowing (0 < k < d <= 127; a file's stamps may be
// decades apart): the same value as the plain expression would give.
std::int64_t fraction_of(std::int64_t span, int k, int d) noexcept {
  return span / d * k + span % d * k / d;
}

// Decodes one logged message. LCM's generated decoders (1.3.1) throw
// std::length_error from std::string instead of returning -1 when damaged data
// gives a string a length of 0 or less (joint_state_t's joint names): that is
// a message that does not decode, not a reason to abandon the replay.
template <typename Message>
bool decode_event(Message& msg, const lcm_eventlog_event_t& ev) noexcept {
  try {
    return msg.decode(ev.data, 0, ev.datalen) >= 0;
  } catch (const std::exception&) {
    return false;
  }
}

// What a recorded joint_state_t tells about its cycle that the raw message does not.
struct RecordedLoopInfo {
  std::int64_t seq = -1;
  std::int64_t run_id = 0;
  std::uint32_t sample_flags = 0;
  std::uint32_t held_joints = 0;  // bit j: joint j carried JOINT_HELD
};

std::uint64_t fnv1a(std::uint64_t h, const void* data, std::size_t n) noexcept {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ULL;
  }
  return h;
}

// The channels of an LCM log and their event counts, from the event headers
// only (the data is skipped, so this is quick). Event layout (LCM's
// eventlog.c): magic u32, eventnum i64, timestamp i64, channel length u32,
// data length u32, channel, data; all big-endian. Stops at the first damaged
// header; the decoding pass (LCM's reader) then sees the same events.
std::map<std::string, std::int64_t> scan_lcm_channels(const std::string& path) {
  std::map<std::string, std::int64_t> channels;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw std::runtime_error("replay: cannot open '" + path + "': " + std::strerror(errno));
  __fsetlocking(f.get(), FSETLOCKING_BYCALLER);
  std::array<unsigned char, 28> h{};
  std::string name;
  const auto be32 = [&h](std::size_t at) {
    return (std::uint32_t{h[at]} << 24) | (std::uint32_t{h[at + 1]} << 16) |
           (std::uint32_t{h[at + 2]} << 8) | std::uint32_t{h[at + 3]};
  };
  while (std::fread(h.data(), 1, h.size(), f.get()) == h.size()) {
    if (be32(0) != kLcmLogMagic) break;
    const std::uint32_t channel_len = be32(20);
    const std::uint32_t data_len = be32(24);
    if (channel_len == 0 || channel_len > 1024) break;
    name.resize(channel_len);
    if (std::fread(name.data(), 1, channel_len, f.get()) != channel_len) break;
    if (std::fseek(f.get(), static_cast<long>(data_len), SEEK_CUR) != 0) break;
    ++channels[name];
  }
  return channels;
}

}  // namespace

ReplaySource::ReplaySource(const ReplaySettings& settings, const SourceContext& context)
    : settings_(settings), context_(context) {
  if (settings_.format != "auto" && settings_.format != "lcm" && settings_.format != "candump") {
    throw std::runtime_error("replay: unknown format '" + settings_.format +
                             "' (auto, lcm or candump)");
  }
  if (settings_.path.empty()) throw std::runtime_error("replay: no input file given");
  if (settings_.channel.empty()) settings_.channel = std::string(kRawBase);
}

ReplayFormat ReplaySource::detect_format(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("replay: cannot open '" + path + "': " + std::strerror(errno));
  std::array<unsigned char, 4> magic{};
  in.read(reinterpret_cast<char*>(magic.data()), 4);
  if (in.gcount() == 4) {
    const std::uint32_t m = (std::uint32_t{magic[0]} << 24) | (std::uint32_t{magic[1]} << 16) |
                            (std::uint32_t{magic[2]} << 8) | std::uint32_t{magic[3]};
    if (m == kLcmLogMagic) return ReplayFormat::kLcm;
  }
  in.clear();
  in.seekg(0);
  std::string line;
  while (std::getline(in, line)) {
    const std::size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos) continue;
    if (line[first] == '(') return ReplayFormat::kCandump;
    break;
  }
  throw std::runtime_error("replay: '" + path +
                           "' is neither an LCM log (lcm-logger) nor a candump -l log; "
                           "give --format to say which it is");
}

void ReplaySource::start() {
  if (!loaded_) {
    const ReplayFormat format = settings_.format == "lcm"       ? ReplayFormat::kLcm
                                : settings_.format == "candump" ? ReplayFormat::kCandump
                                                                : detect_format(settings_.path);
    summary_ = ReplayLoadSummary{};
    summary_.format = format;
    if (format == ReplayFormat::kLcm) {
      load_lcm();
    } else {
      load_candump();
    }
    if (entries_.empty()) {
      throw std::runtime_error("replay: '" + settings_.path + "' holds no encoder sample");
    }
    summary_.samples = static_cast<std::int64_t>(entries_.size());
    summary_.duration_s =
        static_cast<double>(entries_.back().sample.mono_ns - entries_.front().sample.mono_ns) *
        1e-9;
    loaded_ = true;
  }
  next_ = 0;
  last_seq_ = -1;
  stats_ = loaded_stats_;
}

ReadStatus ReplaySource::read(const CycleTime& /*time*/, EncoderSample& out) noexcept {
  if (next_ >= entries_.size()) return ReadStatus::kEndOfStream;
  const Entry& e = entries_[next_++];
  out = e.sample;
  last_seq_ = e.seq;
  return out.present ? ReadStatus::kSample : ReadStatus::kNoSample;
}

std::int64_t ReplaySource::next_sample_mono_ns() const noexcept {
  return next_ < entries_.size() ? entries_[next_].sample.mono_ns : -1;
}

// ---------------------------------------------------------------------------
// LCM logs
// ---------------------------------------------------------------------------

void ReplaySource::load_lcm() {
  const std::string& path = settings_.path;
  // Pass 1: which channels the log holds, to find the raw channel with its prefix.
  const std::map<std::string, std::int64_t> channels = scan_lcm_channels(path);
  std::string raw_channel;
  if (channels.count(settings_.channel) != 0) {
    raw_channel = settings_.channel;
  } else {
    std::vector<std::string> candidates;
    for (const auto& [name, n] : channels) {
      if (ends_with(name, settings_.channel)) candidates.push_back(name);
    }
    if (candidates.size() == 1) {
      raw_channel = candidates.front();
    } else {
      std::string list;
      for (const auto& c : candidates) list += (list.empty() ? "" : ", ") + c;
      if (candidates.empty()) {
        for (const auto& [name, n] : channels) list += (list.empty() ? "" : ", ") + name;
        throw std::runtime_error("replay: '" + path + "' has no channel '" + settings_.channel +
                                 "' (nor one ending in it); channels in the log: " +
                                 (list.empty() ? std::string("none") : list));
      }
      throw std::runtime_error("replay: '" + path + "' has several raw channels (" + list +
                               "); choose one with --channel");
    }
  }
  summary_.channel = raw_channel;
  summary_.prefix = ends_with(raw_channel, kRawBase)
                        ? raw_channel.substr(0, raw_channel.size() - kRawBase.size())
                        : std::string();
  const std::string joint_channel = summary_.prefix + std::string(kJointBase);
  const bool have_joint_channel =
      ends_with(raw_channel, kRawBase) && channels.count(joint_channel) != 0;

  // Pass 2: decode. Messages of one cycle are published palm, joint, raw, so
  // the joint_state of a raw message's seq has just been seen; a small ring
  // by seq covers reordering by the recorder.
  constexpr std::size_t kRing = 256;
  std::array<RecordedLoopInfo, kRing> recent{};
  exodaq::encoder_raw_t raw;
  exodaq::joint_state_t js;
  bool have_run = false;
  std::int64_t previous_seq = -1;
  std::int64_t other_run_id = 0;
  EncoderSample previous{};
  bool have_previous = false;
  EventLog log(path);
  long good_end = 0;  // the file offset just after the last event read whole
  while (EventPtr ev{lcm_eventlog_read_next_event(log.log)}) {
    good_end = std::ftell(log.log->f);
    ++summary_.events;
    const std::string_view channel(ev->channel, static_cast<std::size_t>(ev->channellen));
    if (have_joint_channel && channel == joint_channel) {
      if (!decode_event(js, *ev)) continue;
      RecordedLoopInfo& slot = recent[static_cast<std::size_t>(js.seq) % kRing];
      slot.seq = js.seq;
      slot.run_id = js.run_id;
      slot.sample_flags = static_cast<std::uint32_t>(js.sample_flags);
      slot.held_joints = 0;
      for (int j = 0; j < 6; ++j) {
        if ((js.flags[j] & kJointHeld) != 0) slot.held_joints |= 1U << static_cast<unsigned>(j);
      }
      continue;
    }
    if (channel != raw_channel) continue;
    if (!decode_event(raw, *ev)) {
      ++loaded_stats_.bad_frames;
      if (issues_.size() < kMaxStoredIssues) {
        issues_.push_back(
            {ev->eventnum, "event on " + raw_channel + " does not decode as exodaq.encoder_raw_t"});
      }
      continue;
    }
    // Values no daemon writes (damaged data): a utime whose nanoseconds do not
    // fit in int64 (after 2262), a negative or last-possible seq.
    constexpr std::int64_t kMaxUtime = INT64_MAX / 1000;
    if (raw.utime > kMaxUtime || raw.utime < -kMaxUtime || raw.seq < 0 || raw.seq == INT64_MAX) {
      ++loaded_stats_.bad_frames;
      if (issues_.size() < kMaxStoredIssues) {
        issues_.push_back({ev->eventnum, "event on " + raw_channel +
                                             " has an impossible utime or seq (damaged log)"});
      }
      continue;
    }
    // The daemon encodes every message type once at start-up (all zero);
    // it is not a cycle.
    if (raw.utime == 0 && raw.mono_ns == 0 && raw.seq == 0 && !raw.present) {
      ++summary_.skipped_warmup;
      continue;
    }
    if (!have_run) {
      have_run = true;
      summary_.run_id = raw.run_id;
    } else if (raw.run_id != summary_.run_id) {
      // Another daemon start in the same log: seq restarts, homing restarts.
      // One run is one replay; the others are counted and named.
      if (raw.run_id != other_run_id) {
        other_run_id = raw.run_id;
        if (issues_.size() < kMaxStoredIssues) {
          char text[160];
          std::snprintf(text, sizeof text,
                        "the log holds another daemon run (run_id %016llx); only run %016llx "
                        "is replayed",
                        static_cast<unsigned long long>(raw.run_id),
                        static_cast<unsigned long long>(summary_.run_id));
          issues_.push_back({ev->eventnum, text});
        }
      }
      ++summary_.skipped_other_runs;
      continue;
    }

    Entry e;
    EncoderSample& s = e.sample;
    e.seq = raw.seq;
    s.mono_ns = raw.mono_ns;
    s.wall_ns = raw.utime * 1000;  // the replay path takes utime = wall_ns / 1000: exact
    s.present = raw.present != 0;
    s.board_seq = raw.board_seq;
    for (std::size_t c = 0; c < static_cast<std::size_t>(kChannelCount); ++c) {
      s.count16[c] = static_cast<std::uint16_t>(raw.count16[c]);
      s.index_count16[c] = static_cast<std::uint16_t>(raw.index_count16[c]);
    }
    s.index_latched = static_cast<std::uint32_t>(raw.index_latched);
    s.index_count_valid = static_cast<std::uint32_t>(raw.index_count_valid);
    s.board_state = static_cast<std::uint32_t>(raw.board_state);
    s.board_errors = static_cast<std::uint32_t>(raw.board_errors);
    s.flags = static_cast<std::uint32_t>(raw.source_flags) | sample_flag::kReplay;
    s.channel_fresh = s.present ? 0x3FU : 0U;

    const RecordedLoopInfo& info = recent[static_cast<std::size_t>(raw.seq) % kRing];
    const bool have_info = info.seq == raw.seq && info.run_id == raw.run_id;
    if (have_info) {
      s.flags |= info.sample_flags & kLoopFlags;
      ++summary_.loop_flags_from_joint_state;
    } else if (!have_joint_channel && previous_seq >= 0 && raw.seq > previous_seq + 1) {
      // No joint_state recorded: a seq jump is the live loop skipping
      // cycles after an overrun, and it flags the next cycle LATE.
      s.flags |= sample_flag::kLate;
    }
    if (s.present && (s.flags & sample_flag::kPartial) != 0) {
      if (have_info) {
        std::uint32_t fresh = 0;
        for (std::size_t j = 0; j < context_.joints.size(); ++j) {
          if ((info.held_joints & (1U << j)) == 0) {
            fresh |= 1U << static_cast<unsigned>(context_.joints[j].channel);
          }
        }
        s.channel_fresh = fresh & 0x3FU;
      } else {
        // encoder_raw_t does not say which half arrived: the half whose counts
        // moved; if neither moved, COUNTS_A (it is sent first).
        std::uint32_t moved = 0;
        if (have_previous) {
          for (unsigned c = 0; c < static_cast<unsigned>(kChannelCount); ++c) {
            if (s.count16[c] != previous.count16[c]) moved |= 1U << c;
          }
        }
        s.channel_fresh = (moved & 0x07U) != 0 || (moved & 0x38U) == 0 ? 0x07U : 0x38U;
      }
    }
    if (!s.present) ++loaded_stats_.missing_samples;
    if ((s.flags & sample_flag::kSeqGap) != 0) ++loaded_stats_.seq_gaps;
    if ((s.flags & sample_flag::kBusError) != 0) ++loaded_stats_.bus_errors;
    loaded_stats_.board_errors = s.board_errors;
    ++loaded_stats_.frames;
    previous = s;
    have_previous = true;
    previous_seq = raw.seq;
    entries_.push_back(e);
  }
  // LCM's reader stops at the first damaged event header without telling the
  // caller: compare where it stopped with the file's size, so a truncated or
  // corrupt log is reported instead of silently replaying less.
  {
    const long stopped_at = good_end;
    if (std::fseek(log.log->f, 0, SEEK_END) == 0) {
      const long size = std::ftell(log.log->f);
      if (stopped_at >= 0 && size > stopped_at) {
        issues_.push_back({summary_.events + 1, "log damaged or truncated after event " +
                                                    std::to_string(summary_.events) + ": bytes " +
                                                    std::to_string(stopped_at) + ".." +
                                                    std::to_string(size) + " of '" + path +
                                                    "' were not replayed"});
      }
    }
  }
  summary_.missing = loaded_stats_.missing_samples;
  if (!have_run) {
    throw std::runtime_error("replay: '" + path + "' has no encoder_raw_t message on '" +
                             raw_channel + "'");
  }
}

// ---------------------------------------------------------------------------
// candump logs
// ---------------------------------------------------------------------------

void ReplaySource::load_candump() {
  const std::string& path = settings_.path;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("replay: cannot open '" + path + "': " + std::strerror(errno));
  BoardDecoder decoder{BoardDecoderConfig{}};
  std::uint64_t hash = 0xcbf29ce484222325ULL;

  EncoderSample previous{};
  bool have_previous = false;
  const auto push = [&](EncoderSample s) {
    s.flags |= sample_flag::kReplay;
    if (have_previous && s.present && previous.board_seq >= 0 && s.board_seq >= 0 &&
        (s.flags & sample_flag::kSeqGap) != 0) {
      // The board's cycles in between never reached the bus: replay them as
      // the live loop saw them, missing samples evenly spaced in the gap.
      const int d = can::seq_delta(static_cast<std::uint8_t>(previous.board_seq),
                                   static_cast<std::uint8_t>(s.board_seq));
      for (int k = 1; k < d; ++k) {
        Entry m;
        m.sample = previous;
        m.sample.present = false;
        m.sample.channel_fresh = 0;
        m.sample.index_latched = 0;
        m.sample.index_count_valid = 0;
        m.sample.flags = sample_flag::kMissing | sample_flag::kReplay;
        m.sample.mono_ns = previous.mono_ns + fraction_of(s.mono_ns - previous.mono_ns, k, d);
        m.sample.wall_ns = previous.wall_ns + fraction_of(s.wall_ns - previous.wall_ns, k, d);
        entries_.push_back(m);
        ++loaded_stats_.missing_samples;
      }
    }
    Entry e;
    e.sample = s;
    entries_.push_back(e);
    previous = s;
    have_previous = true;
  };

  std::string line;
  std::int64_t line_no = 0;
  EncoderSample sample;
  while (std::getline(in, line)) {
    ++line_no;
    hash = fnv1a(hash, line.data(), line.size());
    can::CanFrame frame;
    const CandumpError err = parse_candump_line(line, frame);
    if (err == CandumpError::kBlank) continue;
    if (err != CandumpError::kNone) {
      ++summary_.bad_lines;
      if (issues_.size() < kMaxStoredIssues) {
        std::string shown = line.size() > 80 ? line.substr(0, 77) + "..." : line;
        issues_.push_back({line_no, std::string(to_string(err)) + ": \"" + shown + "\""});
      }
      continue;
    }
    ++summary_.frames;
    decoder.on_frame(frame);
    while (decoder.poll_sample(sample)) push(sample);
  }
  if (in.bad()) throw std::runtime_error("replay: error reading '" + path + "'");
  if (decoder.flush(sample)) push(sample);
  summary_.events = line_no;

  const SourceStats d = decoder.stats();
  const std::int64_t inserted_missing = loaded_stats_.missing_samples;
  loaded_stats_ = d;
  loaded_stats_.missing_samples += inserted_missing;
  loaded_stats_.bad_frames += summary_.bad_lines;
  summary_.missing = loaded_stats_.missing_samples;
  summary_.run_id = static_cast<std::int64_t>(hash & 0x7FFF'FFFF'FFFF'FFFFULL);
  if (summary_.run_id == 0) summary_.run_id = 1;
}

}  // namespace exodaq::drivers
