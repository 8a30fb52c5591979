#include "canopen_sim.hpp"

#include <algorithm>
#include <cerrno>
#include <stdexcept>
#include <utility>

#include "board_sim.hpp"
#include "exodaq/common/clock_now.hpp"

namespace exodaq::board_sim {
namespace {

namespace can = drivers::can;
namespace sim = drivers::sim;

constexpr std::int64_t kNsPerMs = 1'000'000;

std::size_t u(int i) noexcept {
  return static_cast<std::size_t>(i);
}

constexpr std::array<CanopenFaultName, co::kSimFaultCount> kFaultNames{{
    {co::SimFault::kNeverBoots, "never_boots", "silence"},
    {co::SimFault::kHeartbeatStops, "heartbeat_stops", ""},
    {co::SimFault::kEmcy, "emcy", "board_error"},
    {co::SimFault::kTpdoMissing, "tpdo_missing", "drop"},
    {co::SimFault::kTpdoLate, "tpdo_late", "delay"},
    {co::SimFault::kWrongPdoLength, "wrong_pdo_length", "wrong_dlc"},
    {co::SimFault::kSyncCounterMismatch, "sync_counter_mismatch", "bad_seq"},
}};

bool fault_active(const CanopenFault& f, double t_s) noexcept {
  return t_s >= f.start_s && (f.duration_s <= 0 || t_s < f.start_s + f.duration_s);
}

}  // namespace

std::span<const CanopenFaultName> canopen_fault_names() noexcept {
  return kFaultNames;
}

std::string_view canopen_fault_name(co::SimFault kind) noexcept {
  for (const CanopenFaultName& f : kFaultNames) {
    if (f.kind == kind) return f.name;
  }
  return "?";
}

const CanopenFaultName* find_canopen_fault(std::string_view name) noexcept {
  for (const CanopenFaultName& f : kFaultNames) {
    if (f.name == name || (!f.v1_name.empty() && f.v1_name == name)) return &f;
  }
  return nullptr;
}

CanopenFault parse_canopen_fault(MapReader& m) {
  std::vector<std::string> names;
  for (const CanopenFaultName& f : kFaultNames) {
    names.emplace_back(f.name);
    if (!f.v1_name.empty()) names.emplace_back(f.v1_name);
  }
  CanopenFault fault;
  fault.kind = find_canopen_fault(m.choice("kind", names))->kind;
  fault.start_s = m.number("at_s");
  if (fault.start_s < 0) m.fail_key("at_s", "at_s must be >= 0");
  fault.duration_s = m.number_or("for_s", 0.0);
  const std::int64_t joint = m.integer_or("joint", 1);
  if (joint < 1 || joint > kCanopenNodes) m.fail_key("joint", "joint must be 1..6");
  fault.joint = static_cast<int>(joint - 1);
  // The v1 kinds' parameters have no meaning for a node: accepted, unused.
  for (const char* key : {"percent", "error_bits", "every", "delay_us"}) m.allow(key);
  m.finish();
  return fault;
}

CanopenFault canopen_fault_from(const sim::SimFault& fault) {
  const std::string_view name = sim::sim_fault_name(fault.kind);
  const CanopenFaultName* f = find_canopen_fault(name);
  if (f == nullptr) {
    throw std::invalid_argument("fault kind '" + std::string(name) +
                                "' has no CANopen counterpart");
  }
  return {f->kind, fault.joint, fault.start_s, fault.duration_s};
}

can::CanIdFilterSet canopen_port_filters(const CanopenSimOptions& options) noexcept {
  can::CanIdFilterSet set;
  set.add({co::cob::kNmt, can::kStandardIdMask});
  set.add({co::cob::kSync, can::kStandardIdMask});
  for (const CanopenNodeOptions& n : options.nodes) {
    set.add({co::cob::sdo_rx(n.node), can::kStandardIdMask});
  }
  return set;
}

CanopenSim::CanopenSim(const sim::SimOptions& rig, const CanopenSimOptions& options,
                       drivers::CanPort& port, std::FILE* truth, std::FILE* answers)
    : rig_(rig), options_(options), port_(port), truth_(truth), answers_(answers) {
  for (int i = 0; i < kCanopenNodes; ++i) {
    const CanopenNodeOptions& n = options_.nodes[u(i)];
    if (!co::is_node_id(n.node)) {
      throw std::invalid_argument("node id " + std::to_string(n.node) + " is not 1..127");
    }
    for (int k = 0; k < i; ++k) {
      if (options_.nodes[u(k)].node == n.node) {
        throw std::invalid_argument("node id " + std::to_string(n.node) + " given twice");
      }
    }
    if (n.total_range < 2) throw std::invalid_argument("total range must be >= 2");
  }
  for (const CanopenFault& f : options_.faults) {
    if (f.joint < 0 || f.joint >= kCanopenNodes) {
      throw std::invalid_argument("fault on joint " + std::to_string(f.joint + 1) +
                                  ": joint must be 1..6");
    }
    if (f.start_s < 0) throw std::invalid_argument("fault start must be >= 0");
  }
  if (options_.sync_overflow == 1 || options_.sync_overflow > co::kSyncCounterMax) {
    throw std::invalid_argument("sync overflow must be 0 or 2..240");
  }
  for (int j = 0; j < kCanopenNodes; ++j) {
    joint_of_channel_[u(rig_.encoders().params(j).channel)] = j;
  }
  for (int i = 0; i < kCanopenNodes; ++i) {
    const CanopenNodeOptions& n = options_.nodes[u(i)];
    const sim::SimEncoderParams& e = rig_.encoders().params(joint_of_channel_[u(i)]);
    co::NodeSimConfig c;
    c.node = n.node;
    c.identity.serial_number = 1000U + static_cast<std::uint32_t>(i);
    c.boot_delay_ns = options_.boot_delay_ns + i * kNsPerMs;
    c.response_ns = options_.response_ns;
    c.heartbeat_ms = options_.heartbeat_ms;
    c.units_per_revolution = static_cast<std::uint32_t>(e.counts_per_rev);
    c.total_range = n.total_range;
    c.has_count_object = n.index_module;
    c.count_object = n.count_object;
    c.has_reference_object = n.index_module;
    c.reference_object = n.reference_object;
    if (options_.sync_producer && i == 0) {
      c.sync_producer = true;
      c.sync_period_ns = options_.sync_period_ns;
      c.sync_overflow = options_.sync_overflow;
    }
    nodes_.push_back(std::make_unique<co::EncoderNodeSim>(c, [this, i](std::int64_t now) {
      const double t = sim_time_s(now);
      const auto range = static_cast<std::int64_t>(options_.nodes[u(i)].total_range);
      const std::int64_t ref = reference_[u(i)] % range;
      return co::SimPosition{position_value(i, t),
                             static_cast<std::uint32_t>(ref < 0 ? ref + range : ref)};
    }));
  }
}

// An absolute encoder counts from its zero, mounted at the joint's index
// angle (the calibration's delta_theta0: what the daemon's offset says the
// zero is); an encoder-interface module counts incrementally from power-up,
// as protocol v1's board does, and latches the count at the index.
std::int64_t CanopenSim::reported(int channel, std::int64_t rig_count) const noexcept {
  if (options_.nodes[u(channel)].index_module) return rig_count;
  return rig_count - rig_.encoders().count_at_index(joint_of_channel_[u(channel)], 0);
}

std::int64_t CanopenSim::count_at(int channel, double t_s) const noexcept {
  const int j = joint_of_channel_[u(channel)];
  const double theta = rig_.motion().position(t_s)[u(j)] + rig_.fault_excursion_rad(j, t_s);
  return reported(channel, rig_.encoders().count_at(j, theta));
}

std::uint32_t CanopenSim::position_value(int channel, double t_s) const noexcept {
  const auto range = static_cast<std::int64_t>(options_.nodes[u(channel)].total_range);
  std::int64_t v = count_at(channel, t_s) % range;
  if (v < 0) v += range;
  return static_cast<std::uint32_t>(v);
}

void CanopenSim::power_on(std::int64_t now) {
  origin_ = now;
  settled_ns_ = now;
  if (truth_ != nullptr) {
    std::fprintf(truth_, "# origin_mono_ns %lld\n", static_cast<long long>(origin_));
  }
  powered_ = true;
  apply_faults(now);
  for (auto& n : nodes_) n->power_on(now);
}

void CanopenSim::apply_faults(std::int64_t now) noexcept {
  const double t = sim_time_s(now);
  std::array<std::array<bool, co::kSimFaultCount>, kCanopenNodes> want{};
  for (const CanopenFault& f : options_.faults) {
    if (fault_active(f, t)) want[u(f.joint)][static_cast<std::size_t>(f.kind)] = true;
  }
  for (int i = 0; i < kCanopenNodes; ++i) {
    for (int k = 0; k < co::kSimFaultCount; ++k) {
      const auto kind = static_cast<co::SimFault>(k);
      const bool w = want[u(i)][static_cast<std::size_t>(k)];
      if (node(i).fault(kind) != w) node(i).set_fault(kind, w, now);
    }
  }
}

// One cycle of the truth: the rig sampled at the SYNC's instant.
void CanopenSim::on_sync(const can::CanFrame& frame, std::int64_t at) noexcept {
  const co::Decoded d = co::decode_frame(frame);
  if (d.kind != co::FrameKind::kSync) return;
  last_sync_ns_ = at;
  sync_ns_[static_cast<std::size_t>(k_ % kSyncHistory)] = at;
  rig_.step_at(k_, at - origin_, frames_, origin_, 0);
  const sim::SimCycle& c = rig_.last_cycle();
  for (int j = 0; j < kCanopenNodes; ++j) {
    const int ch = rig_.encoders().params(j).channel;
    if (rig_.encoders().latched(j)) reference_[u(ch)] = rig_.encoders().latched_count(j);
  }
  std::uint32_t bits = c.applied | pending_bits_;
  pending_bits_ = 0;
  for (int k = 0; k < co::kSimFaultCount; ++k) {
    const auto kind = static_cast<co::SimFault>(k);
    bool any = false;
    for (int i = 0; i < kCanopenNodes; ++i) any = any || node(i).fault(kind);
    if (!any) continue;
    bits |= canopen_fault_bit(kind);
    ++counters_.fault_cycles[static_cast<std::size_t>(k)];
  }
  ++counters_.syncs;
  if (truth_ != nullptr) {
    const unsigned seq = d.sync.has_counter ? d.sync.counter : static_cast<unsigned>(k_ & 0xFF);
    std::fprintf(truth_, "%lld %u %.9f", static_cast<long long>(k_), seq, c.t_s);
    for (double q : c.position) std::fprintf(truth_, " %.12f", q);
    for (int ch = 0; ch < kCanopenNodes; ++ch) {
      std::fprintf(truth_, " %lld", static_cast<long long>(reported(ch, c.count[u(ch)])));
    }
    std::fprintf(truth_, " %u\n", bits);
  }
  ++k_;
}

// A frame on the bus at `at`: every node but its sender takes it.
void CanopenSim::deliver(const can::CanFrame& frame, int from, std::int64_t at) noexcept {
  if (from < 0 || co::decode_frame(frame).kind == co::FrameKind::kSync) on_sync(frame, at);
  for (int i = 0; i < kCanopenNodes; ++i) {
    if (i != from) node(i).on_frame(frame, at);
  }
}

int CanopenSim::send(const can::CanFrame& frame) noexcept {
  int r = 0;
  for (int attempt = 0; attempt < 5; ++attempt) {
    r = port_.send(frame);
    if (r != -EAGAIN && r != -ENOBUFS) return r;
    exodaq::sleep_until_mono(port_.now_mono_ns() + 50'000);  // the TX queue drains
  }
  return r;
}

// Runs the nodes to `now`; what they sent goes to the other nodes (a CAN
// socket does not see its own frames) and to the port, oldest first.
void CanopenSim::settle(std::int64_t now) noexcept {
  settled_ns_ = std::max(settled_ns_, now);
  for (int round = 0; round < 16; ++round) {
    std::vector<std::pair<can::CanFrame, int>> out;
    for (int i = 0; i < kCanopenNodes; ++i) {
      node(i).advance(now);
      can::CanFrame f;
      while (node(i).next_frame(f)) out.emplace_back(f, i);
    }
    if (out.empty()) return;
    std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
      return a.first.mono_ns < b.first.mono_ns;
    });
    for (const auto& [f, from] : out) {
      deliver(f, from, f.mono_ns);
      can::CanFrame tx = f;
      tx.mono_ns = 0;
      tx.wall_ns = 0;
      const int err = port_.is_open() ? send(tx) : -ENODEV;
      if (err == 0) {
        ++counters_.frames_sent;
        record_answer(f, from);
        continue;
      }
      ++counters_.send_failures;
      pending_bits_ |= kSendFailedBit;
    }
  }
}

// A TPDO answers the last SYNC before the instant it was due at (a node
// answers response_ns or its lateness after the SYNC, never before it).
void CanopenSim::record_answer(const can::CanFrame& frame, int channel) noexcept {
  if (answers_ == nullptr || co::decode_frame(frame).kind != co::FrameKind::kTpdo) return;
  const std::int64_t sent = port_.now_mono_ns();
  for (std::int64_t k = k_ - 1; k >= 0 && k >= k_ - kSyncHistory; --k) {
    if (sync_ns_[static_cast<std::size_t>(k % kSyncHistory)] < frame.mono_ns) {
      std::fprintf(answers_, "%lld %d %lld\n", static_cast<long long>(k), channel,
                   static_cast<long long>(sent));
      return;
    }
  }
}

void CanopenSim::poll(std::int64_t now) {
  if (!powered_) power_on(now);
  apply_faults(now);
  if (port_.is_open()) {
    offset_.measure(port_);
    const std::int64_t wall_offset = offset_.ns();
    std::array<can::CanFrame, 64> rx{};
    for (;;) {
      drivers::CanRxInfo info;
      const int n = port_.receive(rx.data(), static_cast<int>(rx.size()), info);
      if (n < 0 && drivers::is_interface_loss(-n)) port_.close();
      if (n <= 0) break;
      for (int i = 0; i < n; ++i) {
        const can::CanFrame& f = rx[u(i)];
        if (f.flags != 0) continue;  // error frames, RTR: nothing for a node
        ++counters_.frames_received;
        // A frame is where the kernel stamped it, never before frames
        // already fed (the nodes' time runs forward).
        const std::int64_t at =
            std::max(f.wall_ns != 0 ? f.wall_ns - wall_offset : now, settled_ns_);
        settle(at);  // the nodes' own frames up to the frame's arrival first
        deliver(f, -1, at);
      }
      if (n < static_cast<int>(rx.size())) break;
    }
  }
  settle(now);
}

std::string CanopenSim::summary() const {
  std::int64_t tpdos = 0;
  for (const auto& n : nodes_) tpdos += n->tpdos_sent();
  std::string s = "BOARD-SIM: protocol=canopen syncs=" + std::to_string(counters_.syncs) +
                  " tpdos=" + std::to_string(tpdos) +
                  " frames=" + std::to_string(counters_.frames_sent) +
                  " received=" + std::to_string(counters_.frames_received) +
                  " send_failures=" + std::to_string(counters_.send_failures);
  for (const CanopenFaultName& f : kFaultNames) {
    s += " " + std::string(f.name) + "=" +
         std::to_string(counters_.fault_cycles[static_cast<std::size_t>(f.kind)]);
  }
  return s;
}

}  // namespace exodaq::board_sim
