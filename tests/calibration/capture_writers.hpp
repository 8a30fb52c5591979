#pragma once
// Writers of the motion-capture exports the calibration reads, for the
// readers' tests: written from the formats' descriptions (the C3D
// specification of c3d.org; Vicon Nexus and OptiTrack Motive CSV exports as
// those programs lay them out), independently of the readers' code. A
// capture is frames of labelled markers at a frame rate, positions in mm,
// a missing position (not seen) as nullopt.
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace exodaq::calibration::writers {

struct Capture {
  std::vector<std::string> labels;
  double rate_hz = 100.0;
  // frames[k][m]: marker m in frame k (mm), nullopt when not seen.
  std::vector<std::vector<std::optional<Eigen::Vector3d>>> frames;
};

// ---------------------------------------------------------------------------
// C3D
// ---------------------------------------------------------------------------

enum class C3dProcessor : std::uint8_t { kIntel = 84, kDec = 85, kMips = 86 };

struct C3dOptions {
  C3dProcessor processor = C3dProcessor::kIntel;
  bool floats = true;                  // false: 16-bit integers times `scale`
  double scale = 0.1;                  // mm per count (integer storage)
  int analog_channels = 2;             // written (and to be skipped) after the points
  int analog_per_frame = 3;            // analog samples per point frame
  std::size_t labels_per_group = 255;  // more go to POINT:LABELS2, ... (as for > 255 points)
  int first_frame = 1;
  std::string units = "mm";
};

class C3dBytes {
 public:
  explicit C3dBytes(C3dProcessor p) : p_(p) {}
  std::string bytes;

  void u8(int v) { bytes.push_back(static_cast<char>(v & 0xFF)); }
  void i16(int v) {
    const auto u = static_cast<std::uint16_t>(v);
    if (p_ == C3dProcessor::kMips) {
      u8(u >> 8);
      u8(u & 0xFF);
    } else {
      u8(u & 0xFF);
      u8(u >> 8);
    }
  }
  void f32(double v) {
    if (p_ == C3dProcessor::kDec) return dec(v);
    const float f = static_cast<float>(v);
    std::uint32_t b = 0;
    std::memcpy(&b, &f, 4);
    if (p_ == C3dProcessor::kMips) {
      for (int s = 24; s >= 0; s -= 8) u8(static_cast<int>(b >> s));
    } else {
      for (int s = 0; s <= 24; s += 8) u8(static_cast<int>(b >> s));
    }
  }
  void text(const std::string& s, std::size_t width) {
    for (std::size_t k = 0; k < width; ++k) u8(k < s.size() ? s[k] : ' ');
  }
  void pad_to_block() {
    while (bytes.size() % 512 != 0) u8(0);
  }

 private:
  // DEC F_floating from its definition: value = ±0.1f × 2^(e − 128), fraction
  // f in 23 bits after the hidden 1; sign, 8-bit exponent and the 7 high
  // fraction bits in the first 16-bit word, the 16 low fraction bits in the
  // second; each word little-endian.
  void dec(double v) {
    if (v == 0) {
      for (int k = 0; k < 4; ++k) u8(0);
      return;
    }
    int e = 0;
    const double m = std::frexp(std::abs(v), &e);  // |v| = m × 2^e, m in [0.5, 1)
    const auto frac = static_cast<std::uint32_t>(std::llround((m - 0.5) * 16777216.0)) & 0x7FFFFF;
    const std::uint32_t sign = v < 0 ? 1 : 0;
    const std::uint32_t exp = static_cast<std::uint32_t>(e + 128);
    const std::uint32_t w0 = (sign << 15) | (exp << 7) | (frac >> 16);
    const std::uint32_t w1 = frac & 0xFFFF;
    u8(static_cast<int>(w0 & 0xFF));
    u8(static_cast<int>(w0 >> 8));
    u8(static_cast<int>(w1 & 0xFF));
    u8(static_cast<int>(w1 >> 8));
  }
  C3dProcessor p_;
};

// One parameter-section entry; `body` holds what follows the offset word.
inline void c3d_entry(C3dBytes& out, int group_id, const std::string& name, const std::string& body,
                      bool last) {
  out.u8(static_cast<int>(name.size()));
  out.u8(group_id);
  out.text(name, name.size());
  out.i16(last ? 0 : static_cast<int>(body.size()) + 2);
  out.bytes += body;
}

inline std::string c3d_write(const Capture& cap, const C3dOptions& o) {
  const int n = static_cast<int>(cap.labels.size());
  const int frames = static_cast<int>(cap.frames.size());
  const int analog_words = o.analog_channels * o.analog_per_frame;
  const double scale = o.floats ? -std::abs(o.scale) : std::abs(o.scale);
  // Parameter section.
  C3dBytes par(o.processor);
  par.u8(1);
  par.u8(0x50);
  par.u8(0);  // blocks: set below
  par.u8(static_cast<int>(o.processor));
  auto body = [&](auto fill) {
    C3dBytes b(o.processor);
    fill(b);
    return b.bytes;
  };
  auto group = [&](int id, const std::string& name) {
    c3d_entry(par, -id, name, body([](C3dBytes& b) { b.u8(0); }), false);
  };
  auto int_param = [&](int gid, const std::string& name, int v) {
    c3d_entry(par, gid, name, body([&](C3dBytes& b) {
                b.u8(2);
                b.u8(0);
                b.i16(v);
                b.u8(0);
              }),
              false);
  };
  auto float_param = [&](int gid, const std::string& name, double v) {
    c3d_entry(par, gid, name, body([&](C3dBytes& b) {
                b.u8(4);
                b.u8(0);
                b.f32(v);
                b.u8(0);
              }),
              false);
  };
  auto labels_param = [&](const std::string& name, std::size_t from, std::size_t to, bool last) {
    std::size_t width = 4;
    for (std::size_t k = from; k < to; ++k) width = std::max(width, cap.labels[k].size());
    c3d_entry(par, 1, name, body([&](C3dBytes& b) {
                b.u8(0xFF);  // -1: characters
                b.u8(2);
                b.u8(static_cast<int>(width));
                b.u8(static_cast<int>(to - from));
                for (std::size_t k = from; k < to; ++k) b.text(cap.labels[k], width);
                b.u8(0);
              }),
              last);
  };
  group(1, "POINT");
  group(2, "ANALOG");
  int_param(1, "USED", n);
  float_param(1, "SCALE", scale);
  float_param(1, "RATE", cap.rate_hz);
  const int param_blocks = 1 + (static_cast<int>(cap.labels.size()) * 40 + 600) / 512;
  const int data_start = 2 + param_blocks;
  int_param(1, "DATA_START", data_start);
  int_param(1, "FRAMES", frames);
  int_param(2, "USED", o.analog_channels);
  float_param(2, "RATE", cap.rate_hz * o.analog_per_frame);
  c3d_entry(par, 1, "UNITS", body([&](C3dBytes& b) {
              b.u8(0xFF);
              b.u8(1);
              b.u8(static_cast<int>(o.units.size()));
              b.text(o.units, o.units.size());
              b.u8(0);
            }),
            false);
  for (std::size_t from = 0, g = 1; from < cap.labels.size(); from += o.labels_per_group, ++g) {
    const std::size_t to = std::min(cap.labels.size(), from + o.labels_per_group);
    labels_param(g == 1 ? "LABELS" : "LABELS" + std::to_string(g), from, to,
                 to == cap.labels.size());
  }
  par.pad_to_block();
  par.bytes[2] = static_cast<char>(par.bytes.size() / 512);
  if (static_cast<int>(par.bytes.size() / 512) > param_blocks) return "";  // labels too long
  while (static_cast<int>(par.bytes.size() / 512) < param_blocks)
    par.bytes += std::string(512, '\0');
  par.bytes[2] = static_cast<char>(param_blocks);

  // Header (block 1).
  C3dBytes head(o.processor);
  head.u8(2);
  head.u8(0x50);
  head.i16(n);
  head.i16(analog_words);
  head.i16(o.first_frame);
  head.i16(o.first_frame + frames - 1);
  head.i16(10);
  head.f32(scale);
  head.i16(data_start);
  head.i16(o.analog_per_frame);
  head.f32(cap.rate_hz);
  head.pad_to_block();

  // Data.
  C3dBytes data(o.processor);
  for (int k = 0; k < frames; ++k) {
    for (int m = 0; m < n; ++m) {
      const auto& p = cap.frames[static_cast<std::size_t>(k)][static_cast<std::size_t>(m)];
      if (o.floats) {
        for (int c = 0; c < 3; ++c) data.f32(p ? (*p)[c] : 0.0);
        data.f32(p ? 3.0 * 256 + 1 : -1.0);  // cameras 0,1; residual 1 · scale
      } else {
        for (int c = 0; c < 3; ++c) {
          data.i16(p ? static_cast<int>(std::lround((*p)[c] / o.scale)) : 0);
        }
        data.i16(p ? (3 << 8) | 2 : -1);
      }
    }
    for (int a = 0; a < analog_words; ++a) {
      if (o.floats) {
        data.f32(1000.0 + a);
      } else {
        data.i16(-2000 + a);
      }
    }
  }
  data.pad_to_block();
  return head.bytes + par.bytes + data.bytes;
}

// ---------------------------------------------------------------------------
// Vicon Nexus CSV (a Devices section first, then Trajectories)
// ---------------------------------------------------------------------------

inline std::string coord(double v) {
  std::ostringstream s;
  s << std::setprecision(10) << v;
  return s.str();
}

inline std::string vicon_write(const Capture& cap, const std::string& subject = "exo") {
  std::ostringstream o;
  o << "Devices\r\n1000\r\n,,Imported Force Plate #1 - Force,,\r\nFrame,Sub "
       "Frame,Fx,Fy,Fz\r\n,,N,N,N\r\n";
  o << "1,0,0.1,0.2,0.3\r\n1,1,0.1,0.2,0.3\r\n\r\n";
  o << "Trajectories\r\n" << cap.rate_hz << "\r\n,";
  for (const auto& l : cap.labels) o << "," << subject << ":" << l << ",,";
  o << "\r\nFrame,Sub Frame";
  for (std::size_t m = 0; m < cap.labels.size(); ++m) o << ",X,Y,Z";
  o << "\r\n,";
  for (std::size_t m = 0; m < cap.labels.size(); ++m) o << ",mm,mm,mm";
  o << "\r\n";
  for (std::size_t k = 0; k < cap.frames.size(); ++k) {
    o << k + 1 << ",0";
    for (const auto& p : cap.frames[k]) {
      if (p) {
        o << "," << coord(p->x()) << "," << coord(p->y()) << "," << coord(p->z());
      } else {
        o << ",,,";
      }
    }
    o << "\r\n";
  }
  o << "\r\nModel Outputs\r\n100\r\n";
  return o.str();
}

// ---------------------------------------------------------------------------
// OptiTrack Motive CSV (format version 1.23): the first marker as a "Marker",
// the others on a rigid body as "Rigid Body Marker" columns, with the rigid
// body's own rotation, position and error columns between.
// ---------------------------------------------------------------------------

inline std::string motive_write(const Capture& cap, bool metres = false) {
  const double f = metres ? 1e-3 : 1.0;
  std::ostringstream o;
  o << "Format Version,1.23,Take Name,exodaq synthetic,Take Notes,,Capture Frame Rate,"
    << cap.rate_hz << ",Export Frame Rate," << cap.rate_hz
    << ",Capture Start Time,2024-05-01 02.15.41.228 PM,Total Frames in Take," << cap.frames.size()
    << ",Total Exported Frames," << cap.frames.size() << ",Rotation Type,Quaternion,Length Units,"
    << (metres ? "Meters" : "Millimeters") << ",Coordinate Space,Global\n\n";
  std::vector<std::string> type{"", "Type"}, name{"", "Name"}, id{"", "ID"}, kind{"", ""},
      axis{"Frame", "Time (Seconds)"};
  auto column = [&](const std::string& t, const std::string& nm, const std::string& k,
                    const std::string& a) {
    type.push_back(t);
    name.push_back(nm);
    id.push_back("\"9E207518D8A311E9\"");
    kind.push_back(k);
    axis.push_back(a);
  };
  for (std::size_t m = 0; m < cap.labels.size(); ++m) {
    if (m == 1) {  // the rigid body itself
      for (const char* a : {"X", "Y", "Z", "W"}) column("Rigid Body", "exo", "Rotation", a);
      for (const char* a : {"X", "Y", "Z"}) column("Rigid Body", "exo", "Position", a);
      column("Rigid Body", "exo", "Mean Marker Error", "");
    }
    const bool rb = m > 0;
    const std::string nm = rb ? "exo:" + cap.labels[m] : cap.labels[m];
    for (const char* a : {"X", "Y", "Z"})
      column(rb ? "Rigid Body Marker" : "Marker", nm, "Position", a);
    if (rb) column("Rigid Body Marker", nm, "Marker Quality", "");
  }
  for (const auto* row : {&type, &name, &id, &kind, &axis}) {
    for (std::size_t c = 0; c < row->size(); ++c) o << (c ? "," : "") << (*row)[c];
    o << "\n";
  }
  for (std::size_t k = 0; k < cap.frames.size(); ++k) {
    o << k << "," << std::fixed << std::setprecision(6) << static_cast<double>(k) / cap.rate_hz
      << std::defaultfloat;
    for (std::size_t m = 0; m < cap.labels.size(); ++m) {
      if (m == 1) o << ",0,0,0,1,0.1,0.2,0.3,0.0001";
      const auto& p = cap.frames[k][m];
      if (p) {
        o << "," << coord(p->x() * f) << "," << coord(p->y() * f) << "," << coord(p->z() * f);
      } else {
        o << ",,,";
      }
      if (m > 0) o << (p ? ",1" : ",");
    }
    o << "\n";
  }
  return o.str();
}

inline void write_file(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

}  // namespace exodaq::calibration::writers
