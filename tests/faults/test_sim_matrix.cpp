// The rest of issue 11's fault matrix on the simulated rig, in-process and on
// the simulated clock: 1 % frame loss, reordered frames, corrupted count
// frames (bad sequence byte, wrong DLC). Each asserts the exact counters and
// the exact cycles flagged, computed from what the simulator did, and that no
// sample published valid is wrong by more than one count.
#include <gtest/gtest.h>

#include <filesystem>

#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/drivers/sim_rig.hpp"
#include "matrix_checks.hpp"
#include "process.hpp"
#include "sim_daemon.hpp"
#include "source_sections.hpp"

using exodaq::joint_state_t;
using exodaq::palm_pose_t;
using exodaq::status_t;
using exodaq::drivers::sim::SimFault;
using exodaq::drivers::sim::unit_random;
using exodaq::test::Cycle;
using exodaq::test::run_scenario;
using exodaq::test::ScenarioResult;
using exodaq::test::seqs_with;
using exodaq::test::sim_config;
using exodaq::test::state_sequence;
using exodaq::test::valid_means_right;

namespace {

const std::int32_t kMissing = joint_state_t::SAMPLE_MISSING;
const std::int32_t kSeqGap = joint_state_t::SAMPLE_SEQ_GAP;
const std::int32_t kOutOfOrder = joint_state_t::SAMPLE_OUT_OF_ORDER;
const std::int32_t kDuplicate = joint_state_t::SAMPLE_DUPLICATE;
const std::int32_t kPartial = joint_state_t::SAMPLE_PARTIAL;

SimFault fault(SimFault::Kind kind, double at, double dur) {
  SimFault f;
  f.kind = kind;
  f.start_s = at;
  f.duration_s = dur;
  return f;
}

// One-cycle windows: cycle `k` only (the window starts half a period before it).
SimFault one_cycle(SimFault::Kind kind, std::int64_t k) {
  return fault(kind, (static_cast<double>(k) - 0.5) * 1e-3, 1e-3);
}

std::vector<std::int64_t> every(std::int64_t first, std::int64_t last, std::int64_t step) {
  std::vector<std::int64_t> v;
  for (std::int64_t k = first; k <= last; k += step) v.push_back(k);
  return v;
}

std::vector<std::int64_t> plus(std::vector<std::int64_t> v, std::int64_t d) {
  for (auto& k : v) k += d;
  return v;
}

void print_counts(const char* name, const status_t& s, int valid) {
  std::printf(
      "MATRIX %s: missing_samples %lld seq_gaps %lld duplicates %lld out_of_order %lld "
      "bad_frames %lld frames %lld valid_poses %d\n",
      name, static_cast<long long>(s.missing_samples), static_cast<long long>(s.seq_gaps),
      static_cast<long long>(s.duplicates), static_cast<long long>(s.out_of_order),
      static_cast<long long>(s.bad_frames), static_cast<long long>(s.frames), valid);
}

}  // namespace

TEST(SimMatrix, OnePercentFrameLossIsCountedExactlyAndNeverValid) {
  auto cfg = sim_config();
  SimFault f = fault(SimFault::Kind::kDrop, 12.0, 10.0);
  f.percent = 1.0;
  exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
      .faults.push_back(f);
  const auto r = run_scenario(cfg, 23.0);
  // The cycles the simulator dropped, and the runs of them (one seq gap each).
  std::vector<std::int64_t> dropped;
  std::int64_t runs = 0;
  for (std::int64_t k = 12000; k < 22000; ++k) {
    if (unit_random(cfg.source.section_as<exodaq::drivers::SimSourceSettings>("sim")->seed, 4,
                    static_cast<std::uint64_t>(k)) *
            100.0 <
        1.0) {
      if (dropped.empty() || dropped.back() != k - 1) ++runs;
      dropped.push_back(k);
    }
  }
  ASSERT_GT(dropped.size(), 50u);
  const auto& s = r.last_status();
  EXPECT_EQ(seqs_with(r, kMissing), dropped);
  EXPECT_EQ(s.missing_samples, static_cast<std::int64_t>(dropped.size()));
  EXPECT_EQ(s.seq_gaps, runs);
  EXPECT_EQ(static_cast<std::int64_t>(seqs_with(r, kSeqGap).size()), runs);
  EXPECT_EQ(s.duplicates, 0);
  EXPECT_EQ(s.out_of_order, 0);
  for (const std::int64_t k : dropped) {
    const Cycle& c = r.cycles[static_cast<std::size_t>(k)];
    ASSERT_FALSE(c.palm.valid) << k;
    ASSERT_TRUE(c.palm.invalid_reason & palm_pose_t::INVALID_SAMPLE) << k;
    for (int j = 0; j < 6; ++j) ASSERT_TRUE(c.joint.flags[j] & joint_state_t::JOINT_HELD) << k;
  }
  // A lone lost cycle never makes a joint stale (stale_ms = 20).
  for (int j = 0; j < 6; ++j) EXPECT_EQ(s.stale_events[j], 0) << j;
  const int valid = valid_means_right(r);
  EXPECT_GT(valid, 10000);
  EXPECT_EQ(state_sequence(r).back(), int{status_t::STATE_RUNNING});
  print_counts("drop 1%", s, valid);
  std::printf("MATRIX drop 1%%: %zu cycles dropped in 10000 (%lld runs)\n", dropped.size(),
              static_cast<long long>(runs));
}

TEST(SimMatrix, ReorderedCountFramesAreDroppedAsOutOfOrderAndTheCycleMissing) {
  // From 12.0 s for 100 ms, every other cycle's COUNTS_A/B reach the bus after
  // the next cycle's: cycles 12000, 12002, ..., 12098 (50 pairs).
  auto cfg = sim_config();
  exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
      .faults.push_back(fault(SimFault::Kind::kReorder, 12.0, 0.1));
  const auto r = run_scenario(cfg, 14.0);
  const auto& s = r.last_status();
  // The decoder does not wait for a late cycle: at its deadline the held-back
  // cycle is missing; the next cycle arrives first (one seq skipped) and the
  // late frames after it are older than what was delivered: dropped, both
  // halves counted out of order, flagged on the next sample.
  EXPECT_EQ(seqs_with(r, kMissing), every(12000, 12098, 2));
  EXPECT_EQ(seqs_with(r, kSeqGap), every(12001, 12099, 2));
  EXPECT_EQ(seqs_with(r, kOutOfOrder), every(12002, 12100, 2));
  EXPECT_EQ(s.missing_samples, 50);
  EXPECT_EQ(s.seq_gaps, 50);
  EXPECT_EQ(s.out_of_order, 100);
  EXPECT_EQ(s.duplicates, 0);
  EXPECT_EQ(s.bad_frames, 0);
  for (std::int64_t k = 12000; k < 12100; k += 2) {
    ASSERT_FALSE(r.cycles[static_cast<std::size_t>(k)].palm.valid) << k;
    // The cycle after a held-back one is complete and right: valid.
    ASSERT_TRUE(r.cycles[static_cast<std::size_t>(k + 1)].palm.valid) << k + 1;
  }
  // A dropped late frame does not spoil the sample it is flagged on.
  EXPECT_TRUE(r.cycles[12100].palm.valid);
  const int valid = valid_means_right(r);
  EXPECT_GT(valid, 2000);
  EXPECT_EQ(state_sequence(r).back(), int{status_t::STATE_RUNNING});
  print_counts("reorder", s, valid);
}

TEST(SimMatrix, ABadSequenceByteDropsTheCycleAsOutOfOrder) {
  // Ten single cycles, 50 ms apart, whose COUNTS_A/B carry seq + 128: older
  // than the last cycle in the uint8 sequence space.
  auto cfg = sim_config();
  const auto bad = every(12001, 12451, 50);
  for (const std::int64_t k : bad)
    exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
        .faults.push_back(one_cycle(SimFault::Kind::kBadSeq, k));
  const auto r = run_scenario(cfg, 14.0);
  const auto& s = r.last_status();
  // Both halves dropped (out of order, flagged on the cycle's own missing
  // sample), the cycle missing, and the next one follows a one-cycle gap.
  EXPECT_EQ(seqs_with(r, kMissing), bad);
  EXPECT_EQ(seqs_with(r, kOutOfOrder), bad);
  EXPECT_EQ(seqs_with(r, kSeqGap), plus(bad, 1));
  EXPECT_EQ(s.missing_samples, 10);
  EXPECT_EQ(s.out_of_order, 20);
  EXPECT_EQ(s.seq_gaps, 10);
  EXPECT_EQ(s.bad_frames, 0);
  for (const std::int64_t k : bad) {
    ASSERT_FALSE(r.cycles[static_cast<std::size_t>(k)].palm.valid) << k;
    ASSERT_TRUE(r.cycles[static_cast<std::size_t>(k + 1)].palm.valid) << k + 1;
  }
  const int valid = valid_means_right(r);
  EXPECT_GT(valid, 2000);
  print_counts("bad seq", s, valid);
}

TEST(SimMatrix, AWrongDlcCountFrameIsABadFrameAndAPartialSample) {
  // Ten single cycles whose COUNTS_B has DLC 6: rejected by the codec, so the
  // cycle closes at its deadline with COUNTS_A only (joints 4-6 held).
  auto cfg = sim_config();
  const auto bad = every(12001, 12451, 50);
  for (const std::int64_t k : bad) {
    exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
        .faults.push_back(one_cycle(SimFault::Kind::kWrongDlc, k));
  }
  const auto r = run_scenario(cfg, 14.0);
  const auto& s = r.last_status();
  EXPECT_EQ(s.bad_frames, 10);
  EXPECT_EQ(seqs_with(r, kPartial), bad);
  EXPECT_EQ(s.missing_samples, 0);
  EXPECT_EQ(s.seq_gaps, 0);
  EXPECT_EQ(s.out_of_order, 0);
  EXPECT_TRUE(seqs_with(r, kMissing | kSeqGap | kOutOfOrder | kDuplicate).empty());
  for (const std::int64_t k : bad) {
    const Cycle& c = r.cycles[static_cast<std::size_t>(k)];
    ASSERT_FALSE(c.palm.valid) << k;
    for (int j = 0; j < 3; ++j) ASSERT_FALSE(c.joint.flags[j] & joint_state_t::JOINT_HELD) << k;
    for (int j = 3; j < 6; ++j) ASSERT_TRUE(c.joint.flags[j] & joint_state_t::JOINT_HELD) << k;
    ASSERT_TRUE(r.cycles[static_cast<std::size_t>(k + 1)].palm.valid) << k + 1;
  }
  const int valid = valid_means_right(r);
  EXPECT_GT(valid, 2000);
  print_counts("wrong dlc", s, valid);
}

TEST(SimMatrix, TheNewFaultKindsAreAvailableFromTheServiceConfig) {
  std::string yaml = exodaq::test::sim_config_text("MATRIX_");
  exodaq::test::replace_once(yaml, "    jitter_us: 0\n",
                             "    jitter_us: 0\n"
                             "    faults:\n"
                             "      - {kind: reorder, at_s: 12, for_s: 0.1}\n"
                             "      - {kind: bad_seq, at_s: 13, for_s: 0.001}\n"
                             "      - {kind: wrong_dlc, at_s: 14, for_s: 0.001}\n");
  const std::string dir = exodaq::test::make_temp_dir("matrix");
  const auto cfg =
      exodaq::settings::load_service_config(exodaq::test::write_config_text(dir, yaml));
  std::filesystem::remove_all(dir);
  ASSERT_EQ(cfg.source.section_as<exodaq::drivers::SimSourceSettings>("sim")->faults.size(), 3u);
  EXPECT_EQ(cfg.source.section_as<exodaq::drivers::SimSourceSettings>("sim")->faults[0].kind,
            SimFault::Kind::kReorder);
  EXPECT_EQ(cfg.source.section_as<exodaq::drivers::SimSourceSettings>("sim")->faults[1].kind,
            SimFault::Kind::kBadSeq);
  EXPECT_EQ(cfg.source.section_as<exodaq::drivers::SimSourceSettings>("sim")->faults[2].kind,
            SimFault::Kind::kWrongDlc);
  EXPECT_DOUBLE_EQ(
      cfg.source.section_as<exodaq::drivers::SimSourceSettings>("sim")->faults[0].duration_s, 0.1);
}
