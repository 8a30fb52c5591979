#pragma once
// An in-memory CAN bus for the CANopen tests: simulated encoder nodes and one
// manager (the test). Every frame a node sends reaches the other nodes and
// the manager, in the order of its stamp; the manager's frames reach every
// node at the time it sends them. Time moves in steps of at most `step_ns`,
// so a node's answer to a frame is due after the frame itself.
#include <algorithm>
#include <cstdint>
#include <memory>
#include <vector>

#include "exodaq/drivers/canopen/node_sim.hpp"

namespace exodaq::drivers::canopen::test {

class SimBus {
 public:
  explicit SimBus(std::int64_t step_ns = 50'000) : step_ns_(step_ns) {}

  EncoderNodeSim& add(const NodeSimConfig& config, PositionSource source) {
    nodes_.push_back(std::make_unique<EncoderNodeSim>(config, std::move(source)));
    return *nodes_.back();
  }
  EncoderNodeSim& node(int i) { return *nodes_[static_cast<std::size_t>(i)]; }
  int size() const { return static_cast<int>(nodes_.size()); }

  void power_on(std::int64_t now) {
    for (auto& n : nodes_) n->power_on(now);
    now_ = now;
  }

  // The manager sends `frame` at `now` (>= the bus time).
  void send(const CanFrame& frame, std::int64_t now) {
    run_until(now);
    for (auto& n : nodes_) n->on_frame(frame, now);
  }

  // Runs the nodes to `until`; the frames the manager received meanwhile are
  // appended to `received`, oldest first.
  void run_until(std::int64_t until, std::vector<CanFrame>* received = nullptr) {
    while (now_ < until) {
      now_ = std::min(until, now_ + step_ns_);
      settle(received);
    }
    settle(received);
  }

  std::int64_t now() const { return now_; }

 private:
  void settle(std::vector<CanFrame>* received) {
    for (;;) {
      std::vector<std::pair<CanFrame, int>> sent;
      for (int i = 0; i < size(); ++i) {
        node(i).advance(now_);
        CanFrame f;
        while (node(i).next_frame(f)) sent.emplace_back(f, i);
      }
      if (sent.empty()) return;
      std::stable_sort(sent.begin(), sent.end(), [](const auto& a, const auto& b) {
        return a.first.mono_ns < b.first.mono_ns;
      });
      for (const auto& [f, from] : sent) {
        for (int i = 0; i < size(); ++i) {
          if (i != from) node(i).on_frame(f, f.mono_ns);
        }
        if (received != nullptr) received->push_back(f);
      }
    }
  }

  std::int64_t step_ns_;
  std::int64_t now_ = 0;
  std::vector<std::unique_ptr<EncoderNodeSim>> nodes_;
};

}  // namespace exodaq::drivers::canopen::test
