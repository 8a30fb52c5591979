// The motion-capture readers (issue 28 part 1) on files written by the test's
// own writers (capture_writers.hpp), from a synthetic capture with gaps: C3D in
// the three processor formats with float and integer storage, Vicon Nexus CSV,
// OptiTrack Motive CSV; selection by label and by id; the bounded stores.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <string>

#include "capture_writers.hpp"
#include "exodaq/calibration/inputs.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "sample_stores.hpp"

namespace exodaq::calibration {
namespace {

using writers::Capture;

// Five markers at 120 Hz for 2 s moving on curves, every 7th sample of marker
// 2 not seen and marker 4 gone for frames 50..59.
Capture synthetic_capture(double rate = 120.0, int frames = 240) {
  Capture c;
  c.labels = {"palm", "forearm", "base1", "base2", "base3"};
  c.rate_hz = rate;
  for (int k = 0; k < frames; ++k) {
    const double t = k / rate;
    std::vector<std::optional<Eigen::Vector3d>> f;
    for (int m = 0; m < 5; ++m) {
      Eigen::Vector3d p(203.3 + 150 * std::sin(0.7 * t + m),
                        849.3 - 120 * std::cos(1.1 * t + 0.3 * m),
                        -224.5 + 90 * std::sin(0.4 * t + 2 * m) + 0.123 * m);
      const bool hidden = (m == 1 && k % 7 == 3) || (m == 3 && k >= 50 && k < 60);
      f.push_back(hidden ? std::nullopt : std::optional<Eigen::Vector3d>(p));
    }
    c.frames.push_back(f);
  }
  return c;
}

class MarkerFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::testing::TempDir() + "/exodaq_marker_files_" + std::to_string(::getpid());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& bytes) {
    const std::string path = dir_ + "/" + name;
    writers::write_file(path, bytes);
    return path;
  }
  std::string dir_;
};

// Every sample of the markers `wanted` (1-based positions) against the capture.
void expect_capture(const MarkerSeries& s, const Capture& c, const std::vector<int>& wanted,
                    double tol_mm) {
  ASSERT_EQ(s.samples.size(), c.frames.size() * wanted.size());
  EXPECT_EQ(s.ids, wanted);
  EXPECT_FALSE(s.info.epoch_times);
  EXPECT_DOUBLE_EQ(s.info.rate_hz, c.rate_hz);
  std::size_t i = 0, gaps = 0;
  for (std::size_t k = 0; k < c.frames.size(); ++k) {
    for (int id : wanted) {
      const MarkerSample& m = s.samples[i++];
      const auto& truth = c.frames[k][static_cast<std::size_t>(id - 1)];
      ASSERT_EQ(m.marker_id, id);
      ASSERT_EQ(m.utime_us, std::llround(1e6 * static_cast<double>(k) / c.rate_hz)) << k;
      ASSERT_EQ(m.present, truth.has_value()) << "frame " << k << " marker " << id;
      if (!truth) {
        ++gaps;
        continue;
      }
      EXPECT_NEAR(m.x * 1e3, truth->x(), tol_mm) << k;
      EXPECT_NEAR(m.y * 1e3, truth->y(), tol_mm) << k;
      EXPECT_NEAR(m.z * 1e3, truth->z(), tol_mm) << k;
    }
  }
  std::size_t expected_gaps = 0;
  for (const auto& f : c.frames) {
    for (int id : wanted) expected_gaps += f[static_cast<std::size_t>(id - 1)] ? 0 : 1;
  }
  EXPECT_EQ(gaps, expected_gaps);
  EXPECT_GT(expected_gaps, 0u);
}

struct C3dCase {
  writers::C3dProcessor processor;
  bool floats;
  const char* name;
};

TEST_F(MarkerFiles, C3dInEveryProcessorFormatAndStorage) {
  const Capture c = synthetic_capture();
  for (const C3dCase& k : {C3dCase{writers::C3dProcessor::kIntel, true, "intel-float"},
                           C3dCase{writers::C3dProcessor::kIntel, false, "intel-int"},
                           C3dCase{writers::C3dProcessor::kDec, true, "dec-float"},
                           C3dCase{writers::C3dProcessor::kDec, false, "dec-int"},
                           C3dCase{writers::C3dProcessor::kMips, true, "mips-float"},
                           C3dCase{writers::C3dProcessor::kMips, false, "mips-int"}}) {
    SCOPED_TRACE(k.name);
    writers::C3dOptions o;
    o.processor = k.processor;
    o.floats = k.floats;
    const std::string path = write(std::string(k.name) + ".c3d", writers::c3d_write(c, o));
    const MarkerSeries s =
        read_markers(path, {marker_ref("palm"), marker_ref("base2"), marker_ref("forearm")});
    EXPECT_EQ(s.info.format, MarkerFormat::kC3d);
    EXPECT_EQ(s.info.labels, c.labels);
    // Floats carry 24 bits (0.0001 mm here), integers 0.1 mm counts.
    const double tol = k.floats ? 2e-4 : 0.05 + 1e-9;
    MarkerSeries sorted = s;
    // read_markers keeps the requested order within each frame.
    expect_capture(sorted, c, {1, 4, 2}, tol);
  }
}

TEST_F(MarkerFiles, C3dLabelsBeyondTheFirstGroupAndMetres) {
  const Capture c = synthetic_capture(100.0, 50);
  writers::C3dOptions o;
  o.labels_per_group = 2;  // POINT:LABELS, LABELS2, LABELS3
  o.units = "m";
  Capture metres = c;
  for (auto& f : metres.frames) {
    for (auto& p : f) {
      if (p) *p *= 1e-3;
    }
  }
  const std::string path = write("labels.c3d", writers::c3d_write(metres, o));
  const MarkerSeries s = read_markers(path, {marker_ref("base3"), marker_ref("2")});
  EXPECT_EQ(s.info.labels, c.labels);
  expect_capture(s, c, {5, 2}, 2e-4);
}

TEST_F(MarkerFiles, ViconNexusTrajectories) {
  const Capture c = synthetic_capture();
  const std::string path = write("vicon.csv", writers::vicon_write(c));
  const MarkerSeries s = read_markers(path, {marker_ref("palm"), marker_ref("exo:base2")});
  EXPECT_EQ(s.info.format, MarkerFormat::kViconCsv);
  ASSERT_EQ(s.info.labels.size(), 5u);
  EXPECT_EQ(s.info.labels[0], "exo:palm");
  expect_capture(s, c, {1, 4}, 1e-6);
}

TEST_F(MarkerFiles, OptiTrackMotiveMarkersAndRigidBodyMarkers) {
  const Capture c = synthetic_capture();
  for (bool metres : {false, true}) {
    SCOPED_TRACE(metres ? "metres" : "millimetres");
    const std::string path = write("motive.csv", writers::motive_write(c, metres));
    const MarkerSeries s =
        read_markers(path, {marker_ref("palm"), marker_ref("forearm"), marker_ref("base3")});
    EXPECT_EQ(s.info.format, MarkerFormat::kMotiveCsv);
    EXPECT_EQ(s.info.start_time, "2024-05-01 02.15.41.228 PM");
    ASSERT_EQ(s.info.labels.size(), 5u);
    EXPECT_EQ(s.info.labels[1], "exo:forearm");  // a rigid-body marker
    expect_capture(s, c, {1, 2, 5}, 1e-6);
  }
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const exodaq::ConfigError& e) {
    return e.what();
  }
  return "no error";
}

TEST_F(MarkerFiles, SelectionErrorsNameTheFileAndItsLabels) {
  Capture c = synthetic_capture(100.0, 10);
  const std::string c3d = write("a.c3d", writers::c3d_write(c, {}));
  EXPECT_EQ(error_of([&] { read_markers(c3d, {marker_ref("thumb")}); }),
            c3d + ": no marker 'thumb' (the file has palm, forearm, base1, base2, base3)");
  EXPECT_EQ(error_of([&] { read_markers(c3d, {}); }),
            c3d +
                ": holds 5 markers (palm, forearm, base1, base2, base3): select one with "
                "--marker-id or use a marker layout");
  EXPECT_EQ(error_of([&] { read_markers(c3d, {marker_ref("9")}); }),
            c3d +
                ": no marker 9: the file has 5 markers, numbered 1.. in its order (palm, "
                "forearm, base1, base2, base3); prefer their labels");
  EXPECT_EQ(error_of([&] {
              read_markers(c3d, {marker_ref("palm"), marker_ref("1")});
            }),
            c3d + ": marker 'palm' is asked for twice");
  c.labels = {"a:palm", "b:palm", "x", "y", "z"};
  const std::string vicon = write("v.csv", writers::vicon_write(c, "s"));
  EXPECT_EQ(error_of([&] { read_markers(vicon, {marker_ref("palm")}); }),
            vicon + ": marker 'palm' matches both 's:a:palm' and 's:b:palm': give the whole label");
  const std::string csv = write("long.csv", "utime_us,x_mm,y_mm,z_mm,marker_id\n1,1,2,3,4\n");
  EXPECT_EQ(error_of([&] { read_markers(csv, {marker_ref("palm")}); }),
            csv +
                ": marker 'palm': the long CSV names its markers by marker_id, not by label "
                "(give the marker's id)");
}

TEST_F(MarkerFiles, DamagedFilesAreClearErrors) {
  const Capture c = synthetic_capture(100.0, 40);
  std::string bytes = writers::c3d_write(c, {});
  const std::string cut = write("cut.c3d", bytes.substr(0, bytes.size() - 1024));
  // 5 points x 4 floats + 6 analog floats a frame, data from block 4.
  EXPECT_EQ(error_of([&] { read_markers(cut, {marker_ref("palm")}); }),
            cut +
                ": C3D: 40 frames of 104 bytes from byte 1536 need 5696 bytes; the file has "
                "5120 (truncated?)");
  bytes[512 + 3] = 99;  // processor type
  const std::string bad = write("bad.c3d", bytes);
  EXPECT_EQ(error_of([&] { read_markers(bad, {marker_ref("palm")}); }),
            bad + ": C3D: unknown processor type 99 (84 Intel, 85 DEC, 86 SGI/MIPS)");
  const std::string nodata =
      write("d.csv", "Devices\n100\n,,Force\nFrame,Sub Frame,Fx\n,,N\n1,0,2\n");
  EXPECT_EQ(error_of([&] { read_markers(nodata, {}); }),
            nodata +
                ": a Vicon Nexus export without a Trajectories section (export the "
                "trajectories)");
  const std::string vicon =
      write("v.csv", "Trajectories\n100\n,,s:a,,\nFrame,Sub Frame,X,Y,Z\n,,mm,mm,mm\n1,0,1,2\n");
  EXPECT_EQ(error_of([&] { read_markers(vicon, {}); }),
            vicon + ":6: s:a: x, y, z must all be numbers or all empty/nan (marker missing)");
  const std::string nul = write("nul.csv", std::string(100000, '\0'));
  EXPECT_EQ(error_of([&] { read_markers(nul, {}); }),
            nul + ":1: NUL byte (a binary file?) at column 1");
  const std::string flat = write("flat.csv", std::string(2 << 20, 'x'));
  EXPECT_EQ(error_of([&] { read_markers(flat, {}); }),
            flat + ":1: line longer than 1048576 bytes (a binary or damaged file?)");
}

// The stores thin evenly past their bound and never lose a fault or a gap.
TEST(SampleStores, EncoderStoreThinsAndKeepsMasksAndGaps) {
  detail::EncoderStore store(8);
  for (int k = 0; k < 40; ++k) {
    EncoderSample s;
    s.utime_us = 1000 * k + (k >= 30 ? 10000 : 0);  // a 10 ms hole before sample 30
    s.theta_r.fill(k);
    if (k == 13) s.fault_mask = 0x04;
    store.push(s);
  }
  const auto kept = store.take();
  ASSERT_EQ(kept.size(), 5u);  // stride 8 after two halvings: 0, 8, 16, 24, 32
  for (std::size_t i = 0; i < kept.size(); ++i) EXPECT_EQ(kept[i].theta_r[0], 8.0 * i);
  EXPECT_EQ(kept[1].fault_mask, 0x04);  // sample 13 lies in [8, 16)
  EXPECT_EQ(kept[0].fault_mask, 0);
  EXPECT_EQ(kept[3].widest_gap_us, 11000);  // 29 -> 30 lies in [24, 32)
  EXPECT_EQ(kept[2].widest_gap_us, 1000);
  EXPECT_EQ(store.thinned(), 35u);
}

TEST(SampleStores, MarkerStoreThinsEveryMarkerAlike) {
  detail::MarkerStore store(10);
  for (int k = 0; k < 20; ++k) {
    for (int id : {1, 2}) {
      MarkerSample s;
      s.utime_us = k;
      s.marker_id = id;
      store.push(s);
    }
  }
  const auto kept = store.take();
  // Full at frame 4 (stride 2), frame 8 (stride 4), frame 16 (stride 8).
  ASSERT_EQ(kept.size(), 6u);  // frames 0, 8, 16 of both markers
  for (std::size_t i = 0; i < kept.size(); ++i) {
    EXPECT_EQ(kept[i].utime_us, static_cast<std::int64_t>(8 * (i / 2)));
    EXPECT_EQ(kept[i].marker_id, static_cast<int>(1 + i % 2));
  }
}

}  // namespace
}  // namespace exodaq::calibration
