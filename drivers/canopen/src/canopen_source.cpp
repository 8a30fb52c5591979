#include "exodaq/drivers/canopen/canopen_source.hpp"

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>

namespace exodaq::drivers::canopen {
namespace {

constexpr std::int64_t kNsPerMs = 1'000'000;

std::size_t at(int i) noexcept {
  return static_cast<std::size_t>(i);
}

std::uint32_t joints_mask(int count) noexcept {
  return count >= 32 ? ~0U : (1U << count) - 1U;
}

const CanopenSourceConfig& checked(const CanopenSourceConfig& config) {
  int joint = -1;
  if (const char* why = validate(config, joint)) {
    throw std::invalid_argument(
        "canopen: " + (joint >= 0 ? "joint " + std::to_string(joint) + ": " : "") + why);
  }
  return config;
}

std::unique_ptr<CanPort> checked(std::unique_ptr<CanPort> port) {
  if (!port) throw std::invalid_argument("canopen: no CAN port");
  return port;
}

// The state line, cut at the diagnostics' limit.
class StateText {
 public:
  void append(std::string_view s) noexcept {
    const std::size_t n = std::min(s.size(), buf_.size() - size_);
    std::copy_n(s.data(), n, buf_.data() + size_);
    size_ += n;
  }
  std::string_view view() const noexcept { return {buf_.data(), size_}; }

 private:
  std::array<char, SourceDiagnostics::kMaxStateBytes> buf_{};
  std::size_t size_ = 0;
};

std::uint32_t board_error_kinds(std::uint32_t faults) noexcept {
  std::uint32_t kinds = 0;
  if ((faults & joint_fault::kEmcy) != 0) kinds |= board_error::kEmcy;
  if ((faults & joint_fault::kNotOperational) != 0) kinds |= board_error::kNotOperational;
  if ((faults & joint_fault::kHeartbeatLost) != 0) kinds |= board_error::kHeartbeatLost;
  if ((faults & joint_fault::kNeverBooted) != 0) kinds |= board_error::kNeverBooted;
  if ((faults & joint_fault::kRebooted) != 0) kinds |= board_error::kRebooted;
  return kinds;
}

}  // namespace

// ---------------------------------------------------------------------------
// Configuration
// ---------------------------------------------------------------------------

namespace {
// Frames the assembler refused, error frames aside (they are the bus's).
std::int64_t rejected_frames(const AssemblerStats& a) noexcept {
  std::int64_t n = 0;
  for (int k = 1; k < kRejectCount; ++k) {
    if (k != static_cast<int>(Reject::kErrorFrame)) n += a.rejected[at(k)];
  }
  return n;
}

// What a stream of converted cycles reports, live or replayed.
SourceStats stream_stats(const AssemblerStats& a, const SampleCounts& c, std::int64_t error_frames,
                         BusState bus, std::uint32_t board_errors) noexcept {
  SourceStats s;
  s.frames = a.frames;
  s.bad_frames = a.wrong_length + a.out_of_range + rejected_frames(a);
  s.missing_samples = c.missing_samples;
  s.seq_gaps = c.seq_gaps;
  s.duplicates = a.duplicates;
  s.bus_errors = error_frames + a.foreign_syncs;
  s.bus_state = bus;
  s.board_errors = board_errors;
  return s;
}
}  // namespace

std::uint16_t heartbeat_producer_ms(const CanopenSourceConfig& config) noexcept {
  if (config.heartbeat_timeout_ns <= 0) return 0;
  const std::int64_t ms = config.heartbeat_timeout_ns / kNsPerMs * 2 / 3;
  return static_cast<std::uint16_t>(std::clamp<std::int64_t>(ms, 1, 0xFFFF));
}

AssemblerConfig assembler_config(const CanopenSourceConfig& config) noexcept {
  AssemblerConfig a;
  a.joint_count = std::clamp(config.joint_count, 0, kChannelCount);
  a.sync_role = config.sync;
  a.sync_overflow = config.sync_overflow;
  a.boot_timeout_ns = config.boot_timeout_ns;
  a.tpdo_deadline_ns = config.read_deadline_ns;
  for (int j = 0; j < a.joint_count; ++j) {
    const CanopenJoint& c = config.joints[at(j)];
    JointConfig& joint = a.joints[at(j)];
    joint.node = c.node;
    joint.tpdo = c.tpdo;
    joint.values = c.values;
    joint.total_range = c.total_range;
    joint.heartbeat_timeout_ns = config.heartbeat_timeout_ns;
  }
  return a;
}

StartupConfig startup_config(const CanopenSourceConfig& config) noexcept {
  StartupConfig s;
  s.node_count = std::clamp(config.joint_count, 0, kChannelCount);
  s.boot_timeout_ns = config.boot_timeout_ns;
  s.sdo_timeout_ns = config.sdo_timeout_ns;
  const std::uint16_t heartbeat_ms = heartbeat_producer_ms(config);
  // Operational is confirmed by a heartbeat: allow a few of them.
  s.operational_timeout_ns = std::max<std::int64_t>(1'000'000'000, 3 * heartbeat_ms * kNsPerMs);
  for (int j = 0; j < s.node_count; ++j) {
    const CanopenJoint& c = config.joints[at(j)];
    NodeSetup& n = s.nodes[at(j)];
    n.node = c.node;
    n.expected_vendor_id = c.vendor_id;
    n.expected_product_code = c.product_code;
    n.wait_operational = heartbeat_ms != 0;
    if (c.configure) {
      n.add_tpdo(c.tpdo);
      if (heartbeat_ms != 0) n.add({{od::kProducerHeartbeatTime, 0}, heartbeat_ms, 2});
    }
  }
  return s;
}

CanPortConfig port_config(const CanopenSourceConfig& config) {
  CanPortConfig p;
  p.interface = config.interface;
  p.rcvbuf_bytes = config.rcvbuf_bytes;
  p.receive_own = true;  // the SYNC's stamp on the bus is the sample's instant
  const auto assembler = std::make_unique<Assembler>(assembler_config(config));
  const WantedIds wanted = assembler->wanted_ids();
  for (int i = 0; i < wanted.count; ++i) p.filters.add({wanted.ids[at(i)], can::kStandardIdMask});
  return p;
}

const char* validate(const CanopenSourceConfig& config, int& joint) noexcept {
  joint = -1;
  if (config.interface.empty() || config.interface.size() > 15) {
    return "interface must be a network interface name (1-15 characters)";
  }
  if (config.joint_count < 1 || config.joint_count > kChannelCount) {
    return "joint count must be between 1 and the published joints (kChannelCount)";
  }
  if (config.read_deadline_ns <= 0) return "read deadline must be positive";
  if (config.reopen_interval_ns <= 0) return "reopen interval must be positive";
  if (config.boot_timeout_ns <= 0) return "boot timeout must be positive";
  if (config.heartbeat_timeout_ns < 0) return "heartbeat timeout must be >= 0";
  if (config.sdo_timeout_ns <= 0) return "SDO timeout must be positive";
  if (!is_sync_overflow(config.sync_overflow)) return "sync_overflow must be 0 or 2..240";
  for (int j = 0; j < config.joint_count; ++j) {
    const CanopenJoint& c = config.joints[at(j)];
    if (c.tpdo.transmission_type != transmission::kEverySync) {
      joint = j;
      return "TPDO transmission type must be 1 (every SYNC)";
    }
    if (c.reference == ReferenceKind::kIndex && !c.values.has_reference) {
      joint = j;
      return "reference: index needs a mapped reference object";
    }
    if (c.reference == ReferenceKind::kAbsolute && c.values.has_reference) {
      joint = j;
      return "a reference object needs reference: index";
    }
    NodeSetup probe;
    probe.node = c.node;
    if (!probe.add_tpdo(c.tpdo)) {
      joint = j;
      return "TPDO mapping needs too many configuration writes";
    }
  }
  const ConfigError e = validate(assembler_config(config));
  if (e.what != nullptr) {
    joint = e.joint;
    if (e.mapping != MappingError::kNone) return to_string(e.mapping).data();
    return e.what;
  }
  return nullptr;
}

// ---------------------------------------------------------------------------
// Source
// ---------------------------------------------------------------------------

CanopenSource::CanopenSource(const CanopenSourceConfig& config, std::unique_ptr<CanPort> port)
    : config_(checked(config)),
      startup_(startup_config(config_)),
      assembler_(assembler_config(config_)),
      link_(checked(std::move(port)), config_.interface, config_.reopen_interval_ns) {
  held_.channel_fresh = 0;
}

void CanopenSource::start() {
  detail_ = {};
  counts_ = {};
  cycling_ = false;
  restart_pending_ = false;
  expected_ = 0;
  arrived_ = 0;
  held_ = {};
  held_.channel_fresh = 0;
  const bool up = link_.start();  // throws when CAN itself is unavailable
  const std::int64_t now = link_.now_mono_ns();
  startup_.begin(now);
  assembler_.reset(now);
  bus_state_ = up ? BusState::kUnknown : BusState::kDown;
}

void CanopenSource::stop() noexcept {
  link_.stop();
  cycling_ = false;
}

// --- FrameSink ---------------------------------------------------------------

void CanopenSource::on_frame(const can::CanFrame& frame) noexcept {
  if ((frame.flags & can::frame_flag::kError) != 0) {
    ++detail_.error_frames;
    can::ErrorPayload error;
    if (can::decode_error(frame, error)) bus_state_ = can::bus_state_after(bus_state_, error);
    assembler_.on_frame(frame);  // counted there too, never data
    return;
  }
  if ((frame.flags & can::frame_flag::kOwn) != 0) {  // what this source sent, read back
    assembler_.on_frame(frame);
    arrived_ = assembler_.answered();
    return;
  }
  if (bus_state_ == BusState::kUnknown) bus_state_ = BusState::kActive;
  startup_.on_frame(frame, frame.mono_ns);
  assembler_.on_frame(frame);
  arrived_ = assembler_.answered();
}

void CanopenSource::on_rx_overflows(std::int64_t dropped) noexcept {
  if (dropped > 0) detail_.rx_overflows += dropped;
}

void CanopenSource::on_link(bool up) noexcept {
  if (up) {
    bus_state_ = BusState::kUnknown;
    restart_pending_ = true;  // the nodes may have reset meanwhile
    return;
  }
  bus_state_ = BusState::kDown;
  cycling_ = false;
}

bool CanopenSource::satisfied() const noexcept {
  return assembler_.cycle_open() && (arrived_ & expected_) == expected_;
}

// --- read ----------------------------------------------------------------------

void CanopenSource::send_startup_frames() noexcept {
  can::CanFrame frame;
  while (startup_.next_frame(frame)) {
    // A frame that cannot go out is lost; the start-up's timeouts repeat it.
    if (link_.up() && link_.send(frame, *this) == 0) {
      ++detail_.startup_frames_sent;
    } else {
      ++detail_.startup_send_failures;
    }
  }
}

std::int64_t CanopenSource::poll_deadline(std::int64_t from, std::int64_t period) const noexcept {
  return std::min(from + config_.read_deadline_ns, from + period - period / 10);
}

void CanopenSource::make_missing(EncoderSample& out, std::int64_t mono_ns,
                                 std::uint32_t flags) noexcept {
  out = held_;
  out.mono_ns = mono_ns;
  out.wall_ns = mono_ns + link_.offset_ns();
  out.present = false;
  out.index_latched = 0;
  out.index_count_valid = 0;
  out.channel_fresh = 0;
  out.flags = sample_flag::kMissing | flags;
  ++counts_.missing_samples;
}

bool CanopenSource::prepare(const CycleTime& time, EncoderSample& out,
                            ReadStatus& status) noexcept {
  const std::int64_t start = time.deadline_mono_ns;
  status = time.catch_up ? ReadStatus::kNothingDue : ReadStatus::kNoSample;
  if (!link_.poll_open(*this)) {
    if (!time.catch_up) make_missing(out, start, sample_flag::kBusError);
    return false;
  }
  if (restart_pending_) {
    restart_pending_ = false;
    cycling_ = false;
    startup_.begin(link_.now_mono_ns());
    ++detail_.startup_restarts;
  }
  if (!link_.drain(*this)) {
    if (!time.catch_up) make_missing(out, start, sample_flag::kBusError);
    return false;
  }
  startup_.advance(link_.now_mono_ns());
  send_startup_frames();
  if (!cycling_) {
    while (assembler_.poll(cycle_)) {
    }  // a SYNC producer's cycles before the nodes ran: nothing to deliver
    if (!startup_.done()) {
      if (!time.catch_up) make_missing(out, start, 0);
      return false;
    }
    cycling_ = true;
  }
  return true;
}

// The joints whose TPDO a cycle waits for: every node that did not fail.
void CanopenSource::expect_answers() noexcept {
  expected_ = 0;
  for (int j = 0; j < config_.joint_count; ++j) {
    if (startup_.progress(j).phase != StartupPhase::kFailed) expected_ |= 1U << j;
  }
  arrived_ = assembler_.answered();
}

ReadStatus CanopenSource::read(const CycleTime& time, EncoderSample& out) noexcept {
  const bool producer = config_.sync == SyncRole::kProducer;
  if (producer && time.catch_up) return ReadStatus::kNothingDue;  // one SYNC, one sample
  const std::int64_t period = time.period_ns > 0 ? time.period_ns : 1'000'000;
  ReadStatus status = ReadStatus::kNoSample;
  if (!prepare(time, out, status)) return status;
  expect_answers();
  return producer ? read_producer(time, period, out) : read_consumer(time, period, out);
}

ReadStatus CanopenSource::read_producer(const CycleTime& time, std::int64_t period,
                                        EncoderSample& out) noexcept {
  // The nodes sample when the SYNC arrives: a late wake moves the sample
  // instant (stamped truthfully, the SYNC's send time) and the answer is
  // waited for from the SYNC on.
  const std::int64_t start = time.deadline_mono_ns;
  const std::int64_t now = link_.now_mono_ns();
  const bool late = now - start > period / 10;
  if (late) ++detail_.late_syncs;
  const can::CanFrame sync = assembler_.begin_cycle(now);
  arrived_ = 0;
  const bool sync_sent = link_.send(sync, *this) == 0;
  if (sync_sent) {
    ++detail_.sync_sent;
    link_.receive_until(poll_deadline(late ? now : start, period), *this);
  } else {
    ++detail_.sync_send_failures;
  }
  assembler_.end_cycle(link_.now_mono_ns());
  bool got = false;
  while (assembler_.poll(cycle_)) {  // the newest one is this cycle's
    if (got) ++detail_.superseded_cycles;
    got = true;
  }
  if (!got) {
    make_missing(out, start, sample_flag::kBusError);
    return ReadStatus::kNoSample;
  }
  convert(cycle_, !sync_sent || !link_.up(), out);
  return out.present ? ReadStatus::kSample : ReadStatus::kNoSample;
}

// Another device sends SYNC, on its own clock: a cycle opens at each SYNC
// received and closes once every expected joint answered or its window
// (read_deadline_us after the SYNC, at most nine tenths of a period) has
// passed; every closed cycle is delivered once, oldest first.
ReadStatus CanopenSource::read_consumer(const CycleTime& time, std::int64_t period,
                                        EncoderSample& out) noexcept {
  const std::int64_t start = time.deadline_mono_ns;
  const std::int64_t window = std::min(config_.read_deadline_ns, period - period / 10);
  if (!time.catch_up && assembler_.cycle_open()) {
    link_.receive_until(std::min(assembler_.last_sync_ns() + window, poll_deadline(start, period)),
                        *this);
  }
  const std::int64_t now = link_.now_mono_ns();
  const std::int64_t window_end = assembler_.last_sync_ns() + window;
  if (assembler_.cycle_open() && ((arrived_ & expected_) == expected_ || now >= window_end)) {
    assembler_.end_cycle(std::min(now, window_end));
  }
  if (assembler_.poll(cycle_)) {
    convert(cycle_, !link_.up(), out);
    return out.present ? ReadStatus::kSample : ReadStatus::kNoSample;
  }
  if (time.catch_up) return ReadStatus::kNothingDue;
  // Nothing closed: the producer's clock drifted just past this wake (the
  // next brings two), unless no SYNC came for one and a half periods.
  const std::int64_t last = assembler_.last_sync_ns();
  if (last != 0 && now - last <= period + period / 2) return ReadStatus::kNothingDue;
  make_missing(out, start, 0);
  return ReadStatus::kNoSample;
}

int CanopenSource::backlog() const noexcept {
  if (config_.sync == SyncRole::kProducer || !link_.up()) return 0;
  return assembler_.queued() + (link_.socket_may_hold_more() ? 1 : 0);
}

void to_sample(const CanopenSourceConfig& config, const CycleSample& cycle,
               std::int64_t wall_offset_ns, std::uint32_t extra_flags, EncoderSample& held,
               SampleCounts& counts, EncoderSample& out) noexcept {
  out = held;
  out.mono_ns = cycle.sync_mono_ns;
  out.wall_ns = cycle.sync_mono_ns + wall_offset_ns;
  out.seq = static_cast<std::int64_t>(cycle.cycle);
  out.seq_modulus = 0;
  out.index_latched = 0;
  out.index_count_valid = 0;
  std::uint32_t fresh = 0;
  std::uint32_t absolute = 0;
  std::uint32_t operational = 0;
  std::uint32_t fault_joints = 0;
  std::uint32_t fault_kinds = 0;
  std::uint32_t flags = extra_flags;
  const int n = std::min(config.joint_count, cycle.joint_count);
  for (int j = 0; j < n; ++j) {
    const JointReading& r = cycle.joints[at(j)];
    const std::uint32_t bit = 1U << j;
    const std::size_t c = at(j);
    out.modulus[c] = static_cast<std::int64_t>(r.modulus);
    if (config.joints[c].reference == ReferenceKind::kAbsolute) absolute |= bit;
    if ((r.faults & joint_fault::kDuplicate) != 0) flags |= sample_flag::kDuplicate;
    if (r.present && (r.faults & kReadingFaults) == 0) {
      fresh |= bit;
      out.position[c] = r.position;
      if (r.has_reference) {
        out.index_position[c] = r.reference;
        if (r.reference_changed) {
          out.index_latched |= bit;
          out.index_count_valid |= bit;
        }
      }
    }
    if (r.state_known && r.state == NmtState::kOperational) operational |= bit;
    if ((r.faults & kNodeFaults) != 0) {
      fault_joints |= bit;
      fault_kinds |= board_error_kinds(r.faults);
    }
  }
  out.absolute = absolute;
  out.channel_fresh = fresh;
  out.present = fresh != 0;
  if (!out.present) {
    flags |= sample_flag::kMissing;
    ++counts.missing_samples;
  } else if (fresh != joints_mask(n)) {
    flags |= sample_flag::kPartial;
    ++counts.partial_samples;
  }
  if (fault_joints != 0) {
    flags |= sample_flag::kBoardError;
    ++counts.board_error_samples;
  }
  if ((cycle.flags & (cycle_flag::kSyncCounterMismatch | cycle_flag::kOverrun)) != 0) {
    flags |= sample_flag::kSeqGap;
    ++counts.seq_gaps;
  }
  if ((cycle.flags & cycle_flag::kForeignSync) != 0) flags |= sample_flag::kBusError;
  out.board_state = operational;
  out.board_errors = (fault_joints & board_error::kJointMask) | fault_kinds;
  out.flags = flags;
  held = out;
}

void CanopenSource::convert(const CycleSample& cycle, bool sync_failed,
                            EncoderSample& out) noexcept {
  const bool bus_error =
      sync_failed || bus_state_ == BusState::kOff || bus_state_ == BusState::kDown;
  to_sample(config_, cycle, link_.offset_ns(), bus_error ? sample_flag::kBusError : 0, held_,
            counts_, out);
}

// --- counters --------------------------------------------------------------------

SourceStats CanopenSource::stats() const noexcept {
  SourceStats s = stream_stats(assembler_.stats(), counts_, detail_.error_frames, bus_state_,
                               held_.board_errors);
  s.rx_overflows = detail_.rx_overflows;
  s.superseded_samples = detail_.superseded_cycles;
  s.late_syncs = detail_.late_syncs;
  return s;
}

void CanopenSource::diagnose(SourceDiagnostics& out) const noexcept {
  link_.diagnose(out);
  StateText text;
  text.append(out.state());

  const AssemblerStats& a = assembler_.stats();
  out.add("sync_sent", detail_.sync_sent);
  out.add("sync_send_failures", detail_.sync_send_failures);
  out.add("late_syncs", detail_.late_syncs);
  out.add("syncs_read_back", a.syncs_read_back);
  out.add("tpdos", a.tpdos);
  out.add("missing_tpdos", a.missing);
  out.add("late_tpdos", a.late);
  out.add("wrong_length_tpdos", a.wrong_length);
  out.add("duplicate_tpdos", a.duplicates);
  out.add("out_of_range_tpdos", a.out_of_range);
  out.add("emcys", a.emcys);
  out.add("boot_ups", a.boot_ups);
  out.add("heartbeat_losses", a.heartbeat_losses);
  out.add("foreign_syncs", a.foreign_syncs);
  out.add("error_frames", detail_.error_frames);
  out.add("partial_samples", counts_.partial_samples);
  out.add("board_error_samples", counts_.board_error_samples);
  out.add("rejected_frames", rejected_frames(a));
  std::int64_t sdo_retries = 0;
  std::int64_t boot_resets = 0;
  std::int64_t reboots = 0;
  int operational = 0;
  int first_not = -1;
  for (int i = 0; i < startup_.node_count(); ++i) {
    const NodeProgress& p = startup_.progress(i);
    sdo_retries += p.sdo_retries;
    boot_resets += p.boot_resets;
    reboots += p.reboots;
    if (p.phase == StartupPhase::kOperational) {
      ++operational;
    } else if (first_not < 0) {
      first_not = i;
    }
  }
  out.add("sdo_retries", sdo_retries);
  out.add("boot_resets", boot_resets);
  out.add("node_reboots", reboots);
  out.add("startup_restarts", detail_.startup_restarts);
  out.add("startup_send_failures", detail_.startup_send_failures);
  out.add("superseded_cycles", detail_.superseded_cycles);

  char count[32];
  std::snprintf(count, sizeof count, ", %d/%d operational", operational, startup_.node_count());
  text.append(count);
  if (first_not >= 0) {
    const NodeProgress& p = startup_.progress(first_not);
    std::snprintf(count, sizeof count, ", node %d ",
                  static_cast<int>(config_.joints[at(first_not)].node));
    text.append(count);
    if (p.phase == StartupPhase::kFailed) {
      text.append("failed: ");
      text.append(to_string(p.failure));
    } else {
      text.append(to_string(p.phase));
    }
  }
  out.set_state(text.view());
}

// ---------------------------------------------------------------------------
// Replay of a candump log
// ---------------------------------------------------------------------------

namespace {
AssemblerConfig replay_assembler_config(const CanopenSourceConfig& config) noexcept {
  AssemblerConfig a = assembler_config(config);
  a.sync_role = SyncRole::kConsumer;  // the recorded SYNCs open the cycles
  return a;
}

// Closes each cycle where the live source did: once every joint it waits for
// answered (here: every joint that ever did), else at the poll deadline.
class CanopenFrameAssembler final : public FrameAssembler {
 public:
  CanopenFrameAssembler(const CanopenSourceConfig& config, std::int64_t period_ns)
      : config_(config),
        assembler_(replay_assembler_config(config)),
        window_ns_(std::min(config.read_deadline_ns, period_ns - period_ns / 10)) {
    held_.channel_fresh = 0;
  }

  void on_frame(const can::CanFrame& frame) noexcept override {
    if (!started_) {
      assembler_.reset(frame.mono_ns);
      started_ = true;
    }
    last_ns_ = frame.mono_ns;
    if (assembler_.cycle_open() && frame.mono_ns > sync_ns_ + window_ns_) {
      assembler_.end_cycle(sync_ns_ + window_ns_);
    }
    can::ErrorPayload error;
    if (can::decode_error(frame, error)) {
      ++error_frames_;
      bus_state_ = bus_state_after(bus_state_, error);
    } else if (bus_state_ == BusState::kUnknown) {
      bus_state_ = BusState::kActive;
    }
    assembler_.on_frame(frame);
    if (frame.id == cob::kSync && frame.flags == 0 && assembler_.cycle_open()) {
      sync_ns_ = frame.mono_ns;  // a SYNC opened the next cycle
      answered_ |= arrived_;
    }
    const std::uint32_t before = arrived_;
    arrived_ = assembler_.answered();
    if (arrived_ == before) return;
    if (answered_ != 0 && assembler_.cycle_open() && (arrived_ & answered_) == answered_) {
      assembler_.end_cycle(frame.mono_ns);
    }
  }
  bool poll(EncoderSample& out) noexcept override {
    if (!assembler_.poll(cycle_)) return false;
    // The recorded stamps are wall time already: no offset to add.
    const bool bus_down = bus_state_ == BusState::kOff || bus_state_ == BusState::kDown;
    to_sample(config_, cycle_, 0, bus_down ? sample_flag::kBusError : 0, held_, counts_, out);
    return true;
  }
  bool finish(EncoderSample& out) noexcept override {
    if (!assembler_.cycle_open()) return false;
    assembler_.end_cycle(std::min(last_ns_, sync_ns_ + window_ns_));
    return poll(out);
  }
  SourceStats stats() const noexcept override {
    return stream_stats(assembler_.stats(), counts_, error_frames_, bus_state_, held_.board_errors);
  }

 private:
  CanopenSourceConfig config_;
  Assembler assembler_;
  std::int64_t window_ns_;  // the live poll deadline after a SYNC
  CycleSample cycle_{};
  EncoderSample held_{};
  SampleCounts counts_{};
  BusState bus_state_ = BusState::kUnknown;
  std::int64_t error_frames_ = 0;
  std::int64_t last_ns_ = 0;
  std::int64_t sync_ns_ = 0;
  std::uint32_t arrived_ = 0;   // joints whose TPDO of the open cycle was accepted
  std::uint32_t answered_ = 0;  // joints that answered an earlier SYNC
  bool started_ = false;
};
}  // namespace

std::unique_ptr<FrameAssembler> make_frame_assembler(const CanopenSourceConfig& config,
                                                     std::int64_t period_ns) {
  return std::make_unique<CanopenFrameAssembler>(checked(config), period_ns);
}

}  // namespace exodaq::drivers::canopen
