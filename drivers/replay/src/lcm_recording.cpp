// Replay of lcm-logger logs: the encoder_raw_t channel is the source of truth;
// the recorded joint_state_t of the same cycle adds what only the loop knew
// (LATE, clock bits, which channels a PARTIAL sample really had).
#include <array>
#include <climits>
#include <cstdio>
#include <map>
#include <stdexcept>

#include "exodaq/drivers/can_codec.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/homing_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq/messages/raw_sample.hpp"
#include "recording.hpp"

namespace exodaq::drivers::replay {

namespace {

// Bits the loop (not the source) adds to a live sample; the raw channel does
// not carry them, the recorded joint_state_t does.
constexpr std::uint32_t kLoopFlags =
    sample_flag::kLate | sample_flag::kClockStep | sample_flag::kClockUnsync;

// What a recorded joint_state_t tells about its cycle that the raw message does not.
struct LoopInfo {
  std::int64_t seq = -1;
  std::int64_t run_id = 0;
  std::uint32_t sample_flags = 0;
  std::uint32_t held_joints = 0;  // bit j: joint j carried JOINT_HELD
};

std::string join(const std::vector<std::string>& names) {
  std::string list;
  for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
  return list;
}

// The raw channel: the one named, or the only one ending in that name.
std::string find_raw_channel(const std::string& path,
                             const std::map<std::string, std::int64_t>& channels,
                             const std::string& wanted) {
  if (channels.count(wanted) != 0) return wanted;
  std::vector<std::string> candidates;
  std::vector<std::string> all;
  for (const auto& [name, n] : channels) {
    all.push_back(name);
    if (name.size() >= wanted.size() &&
        name.compare(name.size() - wanted.size(), wanted.size(), wanted) == 0) {
      candidates.push_back(name);
    }
  }
  if (candidates.size() == 1) return candidates.front();
  if (candidates.empty()) {
    throw std::runtime_error("replay: '" + path + "' has no channel '" + wanted +
                             "' (nor one ending in it); channels in the log: " +
                             (all.empty() ? std::string("none") : join(all)));
  }
  throw std::runtime_error("replay: '" + path + "' has several raw channels (" + join(candidates) +
                           "); choose one with --channel");
}

class LcmLoader {
 public:
  LcmLoader(const ReplaySettings& settings, const SourceContext& context, const Pass* counted,
            Pass& out, EntrySink& sink)
      : settings_(settings), context_(context), counted_(counted), out_(out), sink_(sink) {}

  void load();

 private:
  void choose_channels();
  void on_joint_state(const messages::LogEvent& ev);
  void on_raw(const messages::LogEvent& ev);
  bool accept_run(std::int64_t event_number);
  void add_loop_info(EncoderSample& s);
  void add_partial_channels(EncoderSample& s, bool have_info, const LoopInfo& info) const;
  void count(const EncoderSample& s);
  void on_homing(const messages::LogEvent& ev);
  void follow_counts(const EncoderSample& s);
  void take_resume();

  static constexpr std::size_t kRing = 256;
  const ReplaySettings& settings_;
  const SourceContext& context_;
  const Pass* counted_;  // the first pass, for the second; nullptr: this is the first
  Pass& out_;
  EntrySink& sink_;
  bool stopped_ = false;  // the sink wants no more
  std::string raw_channel_;
  std::string joint_channel_;
  std::string homing_channel_;
  std::array<LoopInfo, kRing> recent_{};
  // First pass: the latest homing_t not yet matched with its raw sample, and
  // each channel's count unwrapped from the first sample (its travel).
  homing_t homing_;
  homing_t pending_;
  bool have_pending_ = false;
  bool have_counts_ = false;
  std::array<std::int64_t, kChannelCount> travel_{};
  std::array<std::int64_t, kChannelCount> last_position_{};
  encoder_raw_t raw_;
  messages::RawVersion raw_version_ = messages::RawVersion::kNone;
  joint_state_t joint_;
  bool have_run_ = false;
  std::int64_t other_run_id_ = 0;
  std::int64_t previous_seq_ = -1;
  EncoderSample previous_{};
  bool have_previous_ = false;
  // The damaged stretch just read past (1 + its index; 0: none) and the raw
  // seq before it; per stretch, the raw seq on either side.
  std::size_t damage_pending_ = 0;
  std::int64_t damage_before_ = -1;
  std::map<std::size_t, std::pair<std::int64_t, std::int64_t>> damage_cost_;
};

// The raw channel, its prefix and the joint_state_t channel beside it: from
// the log's headers, or as the counting pass found them.
void LcmLoader::choose_channels() {
  ReplayLoadSummary& summary = out_.summary;
  if (counted_ != nullptr) {
    summary.channel = raw_channel_ = counted_->summary.channel;
    summary.prefix = counted_->summary.prefix;
    out_.joint_channel = joint_channel_ = counted_->joint_channel;
    return;
  }
  const auto channels = messages::scan_channels(settings_.path);
  raw_channel_ = find_raw_channel(settings_.path, channels, settings_.channel);
  summary.channel = raw_channel_;
  const auto parts = messages::split_channel(raw_channel_);
  const bool standard_name = parts && parts->kind == messages::Kind::kEncoderRaw;
  summary.prefix = standard_name ? parts->prefix : std::string();
  const std::string joint = messages::channel_name(summary.prefix, messages::Kind::kJointState);
  if (standard_name && channels.count(joint) != 0) joint_channel_ = joint;
  out_.joint_channel = joint_channel_;
  const std::string homing = messages::channel_name(summary.prefix, messages::Kind::kHoming);
  if (standard_name && channels.count(homing) != 0) homing_channel_ = homing;
  out_.homing_channel = homing_channel_;
}

void LcmLoader::load() {
  const std::string& path = settings_.path;
  choose_channels();
  ReplayLoadSummary& summary = out_.summary;
  messages::LogReader log(path);
  messages::LogEvent ev;
  while (!stopped_ && log.next(ev)) {
    if (ev.follows_damage) {
      damage_pending_ = log.damage().size();
      damage_before_ = previous_seq_;
    }
    ++summary.events;
    if (!joint_channel_.empty() && ev.channel == joint_channel_) {
      if (counted_ != nullptr) on_joint_state(ev);  // counting needs no loop bits
    } else if (ev.channel == raw_channel_) {
      on_raw(ev);
    } else if (counted_ == nullptr && !homing_channel_.empty() && ev.channel == homing_channel_) {
      on_homing(ev);
    }
  }
  const auto& damage = log.damage();
  for (std::size_t i = 0; i < damage.size(); ++i) {
    const messages::LogDamage& d = damage[i];
    std::string what = "log damaged after event " + std::to_string(d.after_event) + ": bytes " +
                       std::to_string(d.from) + ".." + std::to_string(d.to) + " of '" + path +
                       "': " + d.what;
    if (d.events_lost == 0) {
      out_.note(d.after_event + 1, what + "; the event there was read");
      continue;
    }
    ++summary.damaged_stretches;
    what +=
        "; " +
        (d.events_lost > 0 ? std::to_string(d.events_lost) : std::string("an unknown number of")) +
        (d.events_lost == 1 ? " event" : " events") + " lost, ";
    const auto cost = damage_cost_.find(i);
    if (cost == damage_cost_.end()) {
      what += "the cycles after it are not in the log";
    } else {
      const auto [before, after] = cost->second;
      const std::int64_t n = after - before - 1;
      summary.damaged_cycles += n;
      what +=
          std::to_string(n) + (n == 1 ? " cycle" : " cycles") + " lost with them" +
          (n > 0 ? " (seq " + std::to_string(before + 1) + ".." + std::to_string(after - 1) + ")"
                 : std::string());
    }
    out_.note(d.after_event + 1, what + "; not replayed");
  }
  summary.missing = out_.stats.missing_samples;
  if (!have_run_) {
    throw std::runtime_error("replay: '" + path + "' has no encoder_raw_t message on '" +
                             raw_channel_ + "'");
  }
}

void LcmLoader::on_joint_state(const messages::LogEvent& ev) {
  if (!messages::decode_into(joint_, ev.data, ev.size)) return;
  LoopInfo& slot = recent_[static_cast<std::size_t>(joint_.seq) % kRing];
  slot.seq = joint_.seq;
  slot.run_id = joint_.run_id;
  slot.sample_flags = static_cast<std::uint32_t>(joint_.sample_flags);
  slot.held_joints = 0;
  for (int j = 0; j < kChannelCount; ++j) {
    if ((joint_.flags[j] & joint_state_t::JOINT_HELD) != 0) {
      slot.held_joints |= 1U << static_cast<unsigned>(j);
    }
  }
}

void LcmLoader::on_raw(const messages::LogEvent& ev) {
  raw_version_ = messages::decode_encoder_raw(raw_, ev.data, ev.size);
  if (raw_version_ == messages::RawVersion::kNone) {
    ++out_.stats.bad_frames;
    out_.note(ev.number, "event on " + raw_channel_ + " does not decode as exodaq.encoder_raw_t");
    return;
  }
  // Values no daemon writes (damaged data): a utime whose nanoseconds do not
  // fit in int64 (after 2262), a negative or last-possible seq.
  constexpr std::int64_t kMaxUtime = INT64_MAX / 1000;
  if (raw_.utime > kMaxUtime || raw_.utime < -kMaxUtime || raw_.seq < 0 || raw_.seq == INT64_MAX) {
    ++out_.stats.bad_frames;
    out_.note(ev.number,
              "event on " + raw_channel_ + " has an impossible utime or seq (damaged log)");
    return;
  }
  if (!messages::positions_in_range(raw_)) {
    ++out_.stats.bad_frames;
    out_.note(ev.number, "event on " + raw_channel_ +
                             " has a position or sequence outside its modulus (damaged log)");
    return;
  }
  if (messages::is_startup_message({raw_.utime, raw_.mono_ns, raw_.seq, raw_.run_id}) &&
      !raw_.present) {
    ++out_.summary.skipped_warmup;
    return;
  }
  if (!accept_run(ev.number)) return;
  if (damage_pending_ != 0) {
    if (damage_before_ >= 0 && raw_.seq > damage_before_) {
      damage_cost_[damage_pending_ - 1] = {damage_before_, raw_.seq};
    }
    damage_pending_ = 0;
  }
  Entry e;
  e.seq = raw_.seq;
  messages::from_encoder_raw(raw_, e.sample);
  e.sample.flags |= sample_flag::kReplay;
  add_loop_info(e.sample);
  count(e.sample);
  if (counted_ == nullptr) {
    if (out_.summary.first_seq < 0) out_.summary.first_seq = raw_.seq;
    follow_counts(e.sample);
  }
  previous_ = e.sample;
  have_previous_ = true;
  previous_seq_ = raw_.seq;
  if (!sink_.put(e)) stopped_ = true;
}

// One run is one replay: another daemon start in the same log (seq and homing
// restart) is counted and named, not mixed in.
bool LcmLoader::accept_run(std::int64_t event_number) {
  if (!have_run_) {
    have_run_ = true;
    out_.summary.run_id = raw_.run_id;
    return true;
  }
  if (raw_.run_id == out_.summary.run_id) return true;
  if (raw_.run_id != other_run_id_) {
    other_run_id_ = raw_.run_id;
    char text[160];
    std::snprintf(text, sizeof text,
                  "the log holds another daemon run (run_id %016llx); only run %016llx "
                  "is replayed",
                  static_cast<unsigned long long>(raw_.run_id),
                  static_cast<unsigned long long>(out_.summary.run_id));
    out_.note(event_number, text, false);
  }
  ++out_.summary.skipped_other_runs;
  return false;
}

void LcmLoader::add_loop_info(EncoderSample& s) {
  const LoopInfo& info = recent_[static_cast<std::size_t>(raw_.seq) % kRing];
  const bool have_info = info.seq == raw_.seq && info.run_id == raw_.run_id;
  if (have_info) {
    s.flags |= info.sample_flags & kLoopFlags;
  } else if (joint_channel_.empty() && previous_seq_ >= 0 && raw_.seq > previous_seq_ + 1) {
    // No joint_state recorded: a seq jump is the live loop skipping cycles
    // after an overrun, and it flags the next cycle LATE.
    s.flags |= sample_flag::kLate;
  }
  if (s.present && (s.flags & sample_flag::kPartial) != 0 &&
      raw_version_ == messages::RawVersion::kV1) {
    add_partial_channels(s, have_info, info);
  }
}

void LcmLoader::add_partial_channels(EncoderSample& s, bool have_info, const LoopInfo& info) const {
  if (have_info) {
    std::uint32_t fresh = 0;
    for (std::size_t j = 0; j < context_.joints.size(); ++j) {
      if ((info.held_joints & (1U << j)) == 0) {
        fresh |= 1U << static_cast<unsigned>(context_.joints[j].channel);
      }
    }
    s.channel_fresh = fresh & kAllChannels;
    return;
  }
  // Version 1 does not say which half arrived: the half whose counts
  // moved; if neither moved, COUNTS_A (it is sent first).
  std::uint32_t moved = 0;
  if (have_previous_) {
    for (unsigned c = 0; c < static_cast<unsigned>(kChannelCount); ++c) {
      if (s.position[c] != previous_.position[c]) moved |= 1U << c;
    }
  }
  s.channel_fresh = (moved & 0x07U) != 0 || (moved & 0x38U) == 0 ? 0x07U : 0x38U;
}

// First pass: the homing records of the run. The first one whose raw sample
// is in the log too says where the live joints stood (take_resume).
void LcmLoader::on_homing(const messages::LogEvent& ev) {
  if (!messages::decode_into(homing_, ev.data, ev.size)) {
    out_.note(ev.number, "event on " + homing_channel_ + " does not decode as exodaq.homing_t");
    return;
  }
  if (messages::is_startup_message({homing_.utime, homing_.mono_ns, homing_.seq, homing_.run_id}))
    return;
  if (have_run_ && homing_.run_id != out_.summary.run_id) return;
  if (have_run_) ++out_.summary.homing_records;
  if (out_.summary.resumed_at_seq >= 0) return;
  pending_ = homing_;
  have_pending_ = true;
  if (have_run_ && previous_seq_ == pending_.seq) take_resume();
}

// First pass: each channel's count unwrapped from the first sample (a held
// count repeats, so every sample may be unwrapped), then a homing record of
// this very cycle, logged before it, is taken.
void LcmLoader::follow_counts(const EncoderSample& s) {
  for (std::size_t c = 0; c < kChannelCount; ++c) {
    if (have_counts_) travel_[c] += wrapped_delta(last_position_[c], s.position[c], s.modulus[c]);
    last_position_[c] = s.position[c];
  }
  have_counts_ = true;
  if (!have_pending_ || out_.summary.resumed_at_seq >= 0) return;
  if (pending_.run_id != out_.summary.run_id || pending_.seq < raw_.seq) {
    have_pending_ = false;  // its cycle is not in the log: wait for the next record
  } else if (pending_.seq == raw_.seq) {
    take_resume();
  }
}

// The live count at the first sample is the record's count less the travel
// since; a joint whose reference changed in the record's own cycle started
// that cycle unhomed (the replay homes it on the recorded index itself).
void LcmLoader::take_resume() {
  have_pending_ = false;
  if (out_.summary.homing_records == 0) ++out_.summary.homing_records;
  out_.summary.resumed_at_seq = pending_.seq;
  for (std::size_t j = 0; j < context_.joints.size(); ++j) {
    const auto ch = static_cast<std::size_t>(context_.joints[j].channel) % kChannelCount;
    JointResume& r = out_.resume[j];
    r.counted = pending_.counted[j] != 0;
    r.count = pending_.count[j] - travel_[ch];
    r.powerup_count = pending_.powerup_count[j];
    const bool changed = (pending_.changed & (1 << j)) != 0;
    r.homing = changed ? std::int8_t{0} : pending_.homing[j];
    r.index_count = pending_.index_count[j];
    r.index_turns = pending_.index_turns[j];
  }
}

void LcmLoader::count(const EncoderSample& s) {
  SourceStats& st = out_.stats;
  if (!s.present) ++st.missing_samples;
  if ((s.flags & sample_flag::kSeqGap) != 0) ++st.seq_gaps;
  if ((s.flags & sample_flag::kBusError) != 0) ++st.bus_errors;
  st.board_errors = s.board_errors;
  ++st.frames;
}

}  // namespace

void read_lcm(const ReplaySettings& settings, const SourceContext& context, const Pass* counted,
              Pass& out, EntrySink& sink) {
  try {
    LcmLoader(settings, context, counted, out, sink).load();
  } catch (const messages::LogError& e) {
    throw std::runtime_error(std::string("replay: ") + e.what());
  }
}

}  // namespace exodaq::drivers::replay
