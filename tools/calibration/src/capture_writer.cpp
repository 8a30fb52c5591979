#include "exodaq/calibration/capture_writer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace exodaq::calibration {

namespace {

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4f", v);
  return buf;
}

// --- C3D, Intel: little-endian 16-bit words, IEEE floats -------------------------

struct Bytes {
  std::string b;
  void u8(int v) { b.push_back(static_cast<char>(v & 0xFF)); }
  void i16(int v) {
    const auto u = static_cast<std::uint16_t>(v);
    u8(u & 0xFF);
    u8(u >> 8);
  }
  void f32(double v) {
    const float f = static_cast<float>(v);
    std::uint32_t u = 0;
    std::memcpy(&u, &f, 4);
    for (int s = 0; s < 32; s += 8) u8(static_cast<int>(u >> s));
  }
  void chars(const std::string& s, std::size_t n) {
    for (std::size_t k = 0; k < n; ++k) u8(k < s.size() ? s[k] : ' ');
  }
  void block() {
    while (b.size() % 512 != 0) u8(0);
  }
};

// A parameter-section entry: name, group id (negative: a group), what follows
// the offset, and the offset to the next entry (0: the last).
void entry(Bytes& out, int id, const std::string& name, const Bytes& rest, bool last) {
  out.u8(static_cast<int>(name.size()));
  out.u8(id);
  out.chars(name, name.size());
  out.i16(last ? 0 : static_cast<int>(rest.b.size()) + 2);
  out.b += rest.b;
}

Bytes scalar(int type, double v) {
  Bytes r;
  r.u8(type);
  r.u8(0);
  if (type == 2) r.i16(static_cast<int>(v));
  if (type == 4) r.f32(v);
  r.u8(0);
  return r;
}

Bytes strings(const std::vector<std::string>& s) {
  std::size_t width = 1;
  for (const auto& x : s) width = std::max(width, x.size());
  Bytes r;
  r.u8(-1);
  r.u8(2);
  r.u8(static_cast<int>(width));
  r.u8(static_cast<int>(s.size()));
  for (const auto& x : s) r.chars(x, width);
  r.u8(0);
  return r;
}

}  // namespace

std::string long_csv_bytes(const Capture& c, std::int64_t epoch_start_us) {
  std::string out = "utime_us,x_mm,y_mm,z_mm,marker_id\n";
  for (std::size_t k = 0; k < c.frames.size(); ++k) {
    const auto t = epoch_start_us + static_cast<std::int64_t>(
                                        std::llround(1e6 * static_cast<double>(k) / c.rate_hz));
    for (std::size_t m = 0; m < c.labels.size(); ++m) {
      const auto& p = c.frames[k][m];
      out += std::to_string(t) + ",";
      out += p ? num(p->x()) + "," + num(p->y()) + "," + num(p->z()) : std::string(",,");
      out += "," + std::to_string(c.ids.at(m)) + "\n";
    }
  }
  return out;
}

std::string c3d_bytes(const Capture& c) {
  const int points = static_cast<int>(c.labels.size());
  const int frames = static_cast<int>(c.frames.size());
  if (points > 255 || frames > 65535)
    throw std::invalid_argument("C3D writer: too many points or frames");
  Bytes par;
  par.u8(1);
  par.u8(0x50);
  par.u8(0);   // blocks, below
  par.u8(84);  // Intel
  Bytes group;
  group.u8(0);
  entry(par, -1, "POINT", group, false);
  entry(par, 1, "USED", scalar(2, points), false);
  entry(par, 1, "SCALE", scalar(4, -1.0), false);  // negative: float storage
  entry(par, 1, "RATE", scalar(4, c.rate_hz), false);
  entry(par, 1, "FRAMES", scalar(2, frames), false);
  entry(par, 1, "UNITS", strings({"mm"}), false);
  Bytes labels = strings(c.labels);
  const std::size_t fixed = par.b.size() + 80 + labels.b.size();
  const int blocks = static_cast<int>((fixed + 511) / 512);
  entry(par, 1, "DATA_START", scalar(2, 2 + blocks), false);
  entry(par, 1, "LABELS", labels, true);
  par.block();
  while (static_cast<int>(par.b.size() / 512) < blocks) par.b += std::string(512, '\0');
  par.b[2] = static_cast<char>(par.b.size() / 512);

  Bytes head;
  head.u8(2);
  head.u8(0x50);
  head.i16(points);
  head.i16(0);  // no analog
  head.i16(1);
  head.i16(frames);
  head.i16(0);
  head.f32(-1.0);
  head.i16(2 + static_cast<int>(par.b.size() / 512));
  head.i16(0);
  head.f32(c.rate_hz);
  head.block();

  Bytes data;
  for (const auto& f : c.frames) {
    for (const auto& p : f) {
      for (int k = 0; k < 3; ++k) data.f32(p ? (*p)[k] : 0.0);
      data.f32(p ? 0.0 : -1.0);  // residual: negative marks an invalid point
    }
  }
  data.block();
  return head.b + par.b + data.b;
}

std::string vicon_csv_bytes(const Capture& c, const std::string& subject) {
  std::string out = "Trajectories\r\n" + num(c.rate_hz) + "\r\n,";
  for (const auto& l : c.labels) out += "," + subject + ":" + l + ",,";
  out += "\r\nFrame,Sub Frame";
  for (std::size_t m = 0; m < c.labels.size(); ++m) out += ",X,Y,Z";
  out += "\r\n,";
  for (std::size_t m = 0; m < c.labels.size(); ++m) out += ",mm,mm,mm";
  out += "\r\n";
  for (std::size_t k = 0; k < c.frames.size(); ++k) {
    out += std::to_string(k + 1) + ",0";
    for (const auto& p : c.frames[k]) {
      out += p ? "," + num(p->x()) + "," + num(p->y()) + "," + num(p->z()) : std::string(",,,");
    }
    out += "\r\n";
  }
  return out;
}

std::string motive_csv_bytes(const Capture& c, const std::string& start_time) {
  const std::string n = std::to_string(c.frames.size());
  std::string out =
      "Format Version,1.23,Take Name,exodaq example,Take Notes,,Capture Frame Rate," +
      num(c.rate_hz) + ",Export Frame Rate," + num(c.rate_hz) + ",Capture Start Time," +
      start_time + ",Total Frames in Take," + n + ",Total Exported Frames," + n +
      ",Rotation Type,Quaternion,Length Units,Millimeters,Coordinate Space,Global\n\n";
  std::string type = ",Type", name = ",Name", id = ",ID", kind = ",", axis = "Frame,Time (Seconds)";
  for (std::size_t m = 0; m < c.labels.size(); ++m) {
    for (const char* a : {"X", "Y", "Z"}) {
      type += ",Marker";
      name += "," + c.labels[m];
      id += "," + std::to_string(m + 1);
      kind += ",Position";
      axis += std::string(",") + a;
    }
  }
  out += type + "\n" + name + "\n" + id + "\n" + kind + "\n" + axis + "\n";
  for (std::size_t k = 0; k < c.frames.size(); ++k) {
    char t[32];
    std::snprintf(t, sizeof t, "%.6f", static_cast<double>(k) / c.rate_hz);
    out += std::to_string(k) + "," + t;
    for (const auto& p : c.frames[k]) {
      out += p ? "," + num(p->x()) + "," + num(p->y()) + "," + num(p->z()) : std::string(",,,");
    }
    out += "\n";
  }
  return out;
}

}  // namespace exodaq::calibration
