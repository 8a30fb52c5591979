// C3D point data (the public C3D file format specification, c3d.org): 512-byte
// blocks; block 1 the header, the parameter section at the block its first
// byte names (byte 2 is 0x50), the 3-D data where the header's word 9 or
// POINT:DATA_START says. The parameter section's fourth byte gives the
// processor type and with it the number formats of the whole file:
//   84 Intel: little-endian integers, IEEE floats;
//   85 DEC: little-endian integers, VAX F floats (exponent bias 128, the two
//      16-bit halves swapped);
//   86 SGI/MIPS: big-endian integers and IEEE floats.
// A negative POINT:SCALE means floating-point storage (x, y, z, residual as
// floats); a positive one 16-bit integers times the scale. A negative
// residual word marks an invalid point (a gap). Each frame holds the points,
// then the analog samples (skipped). Labels from POINT:LABELS, LABELS2, ...
// Read as a stream: only the selected points of each frame are kept.
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <optional>

#include "csv_text.hpp"
#include "exodaq/common/files.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "marker_readers.hpp"
#include "sample_stores.hpp"

namespace exodaq::calibration::detail {

using exodaq::ConfigError;

namespace {

constexpr std::size_t kBlock = 512;
constexpr std::uint8_t kKey = 0x50;
enum class Processor : std::uint8_t { kIntel = 84, kDec = 85, kMips = 86 };

// Numbers in the file's formats.
struct Codec {
  Processor p = Processor::kIntel;

  std::uint16_t u16(const unsigned char* b) const {
    return p == Processor::kMips ? static_cast<std::uint16_t>((b[0] << 8) | b[1])
                                 : static_cast<std::uint16_t>((b[1] << 8) | b[0]);
  }
  std::int16_t i16(const unsigned char* b) const { return static_cast<std::int16_t>(u16(b)); }
  float f32(const unsigned char* b) const {
    std::uint32_t bits = 0;
    if (p == Processor::kMips) {
      bits = (std::uint32_t{b[0]} << 24) | (std::uint32_t{b[1]} << 16) |
             (std::uint32_t{b[2]} << 8) | b[3];
    } else if (p == Processor::kIntel) {
      bits = (std::uint32_t{b[3]} << 24) | (std::uint32_t{b[2]} << 16) |
             (std::uint32_t{b[1]} << 8) | b[0];
    } else {
      // VAX F: word 0 (bytes 0-1, little-endian) holds sign, exponent and the
      // high fraction bits, word 1 the low fraction: IEEE's layout with the
      // halves swapped and the exponent 2 higher (bias 128, hidden bit 0.1).
      bits = (std::uint32_t{b[1]} << 24) | (std::uint32_t{b[0]} << 16) |
             (std::uint32_t{b[3]} << 8) | b[2];
      const std::uint32_t exponent = (bits >> 23) & 0xFF;
      if (exponent == 0) return 0.0f;  // zero (or the reserved operand)
      if (exponent <= 2) {
        float v;
        std::memcpy(&v, &bits, 4);
        return std::ldexp(v, -2);
      }
      bits -= 2U << 23;
    }
    float v;
    std::memcpy(&v, &bits, 4);
    return v;
  }
};

// One parameter: its type (-1 char, 1 byte, 2 int16, 4 float), dimensions, data.
struct Parameter {
  int type = 0;
  std::vector<int> dims;
  std::vector<unsigned char> data;

  std::size_t count() const {
    std::size_t n = 1;
    for (int d : dims) n *= static_cast<std::size_t>(d);
    return n;
  }
  // The first value as a number (int16 read unsigned when `unsigned16`).
  std::optional<double> number(const Codec& c, bool unsigned16 = false) const {
    if (data.empty()) return std::nullopt;
    if (type == 2 && data.size() >= 2) {
      return unsigned16 ? double(c.u16(data.data())) : double(c.i16(data.data()));
    }
    if (type == 4 && data.size() >= 4) return double(c.f32(data.data()));
    if (type == 1) return double(static_cast<std::int8_t>(data[0]));
    return std::nullopt;
  }
  // A 2-D character array as strings (trailing blanks dropped); 1-D: one string.
  std::vector<std::string> strings() const {
    std::vector<std::string> out;
    if (type != -1 || dims.empty()) return out;
    const std::size_t len = static_cast<std::size_t>(dims[0]);
    const std::size_t n = dims.size() == 1 ? 1 : count() / std::max<std::size_t>(len, 1);
    for (std::size_t k = 0; k < n && (k + 1) * len <= data.size(); ++k) {
      std::string s(reinterpret_cast<const char*>(data.data()) + k * len, len);
      const auto end = s.find_last_not_of(std::string(" \0", 2));
      s.erase(end == std::string::npos ? 0 : end + 1);
      out.push_back(s);
    }
    return out;
  }
};

std::string upper(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::toupper(c); });
  return s;
}

// "GROUP:NAME" -> parameter.
using Parameters = std::map<std::string, Parameter>;

// Reads exactly n bytes at `offset`; false when the file ends first.
bool read_at(int fd, std::int64_t offset, unsigned char* out, std::size_t n) {
  std::size_t got = 0;
  while (got < n) {
    const ssize_t r =
        ::pread(fd, out + got, n - got, static_cast<off_t>(offset + std::int64_t(got)));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    got += static_cast<std::size_t>(r);
  }
  return true;
}

// The parameter section: groups (negative id) and parameters (positive id, of
// that group), each with a signed 16-bit offset to the next; 0 ends the list.
Parameters parse_parameters(const std::vector<unsigned char>& sec, const Codec& c,
                            const std::string& name) {
  std::map<int, std::string> groups;
  std::vector<std::pair<int, std::pair<std::string, Parameter>>> params;
  std::size_t pos = 4;
  while (pos + 2 <= sec.size()) {
    const int nchar = std::abs(static_cast<std::int8_t>(sec[pos]));
    const int id = static_cast<std::int8_t>(sec[pos + 1]);
    if (nchar == 0 || id == 0) break;
    if (pos + 2 + static_cast<std::size_t>(nchar) + 2 > sec.size()) break;
    std::string pname(reinterpret_cast<const char*>(&sec[pos + 2]),
                      static_cast<std::size_t>(nchar));
    const std::size_t off_at = pos + 2 + static_cast<std::size_t>(nchar);
    const int offset = c.i16(&sec[off_at]);
    std::size_t p = off_at + 2;
    if (id < 0) {
      groups[-id] = upper(pname);
    } else if (p + 2 <= sec.size()) {
      Parameter par;
      par.type = static_cast<std::int8_t>(sec[p]);
      const int nd = sec[p + 1];
      p += 2;
      if (p + static_cast<std::size_t>(nd) > sec.size()) break;
      for (int d = 0; d < nd; ++d) par.dims.push_back(sec[p + static_cast<std::size_t>(d)]);
      p += static_cast<std::size_t>(nd);
      const std::size_t bytes = par.count() * static_cast<std::size_t>(std::abs(par.type));
      if (std::abs(par.type) != 1 && std::abs(par.type) != 2 && std::abs(par.type) != 4) {
        throw ConfigError(
            name, 0, "C3D parameter " + pname + ": unknown data type " + std::to_string(par.type));
      }
      if (p + bytes > sec.size()) {
        throw ConfigError(name, 0, "C3D parameter " + pname + " runs past the parameter section");
      }
      par.data.assign(sec.begin() + static_cast<std::ptrdiff_t>(p),
                      sec.begin() + static_cast<std::ptrdiff_t>(p + bytes));
      params.push_back({id, {upper(pname), std::move(par)}});
    }
    if (offset <= 0) break;
    pos = off_at + static_cast<std::size_t>(offset);
  }
  Parameters out;
  for (auto& [gid, np] : params) {
    const auto g = groups.find(gid);
    if (g != groups.end()) out[g->second + ":" + np.first] = std::move(np.second);
  }
  return out;
}

// What the header and parameters say about the 3-D data.
struct Layout {
  Codec codec;
  std::size_t points = 0;
  std::size_t analog_words = 0;  // analog values per 3-D frame (skipped)
  std::int64_t frames = 0;
  double scale = 1.0;  // integer storage: units per count
  bool floats = false;
  double rate = 0;
  double to_m = 1e-3;
  std::int64_t data_start = 0;  // byte
  std::vector<std::string> labels;
  std::size_t frame_bytes() const { return (4 * points + analog_words) * (floats ? 4 : 2); }
};

const Parameter* find(const Parameters& p, const std::string& key) {
  const auto it = p.find(key);
  return it == p.end() ? nullptr : &it->second;
}

std::vector<std::string> point_labels(const Parameters& p, std::size_t points) {
  std::vector<std::string> labels;
  for (int k = 1; labels.size() < points; ++k) {
    const Parameter* l = find(p, k == 1 ? "POINT:LABELS" : "POINT:LABELS" + std::to_string(k));
    if (l == nullptr) break;
    for (const auto& s : l->strings()) labels.push_back(s);
  }
  labels.resize(points);
  for (std::size_t k = 0; k < points; ++k) {
    if (labels[k].empty()) labels[k] = "point" + std::to_string(k + 1);  // unlabelled
  }
  return labels;
}

// Frames: the header's first..last, or the TRIAL fields and POINT:FRAMES of
// writers that pass 65535 frames.
std::int64_t frame_count(const unsigned char* head, const Parameters& p, const Codec& c) {
  std::int64_t n = std::int64_t{c.u16(head + 8)} - std::int64_t{c.u16(head + 6)} + 1;
  const Parameter* s = find(p, "TRIAL:ACTUAL_START_FIELD");
  const Parameter* e = find(p, "TRIAL:ACTUAL_END_FIELD");
  if (s && e && s->type == 2 && e->type == 2 && s->data.size() >= 4 && e->data.size() >= 4) {
    const auto field = [&](const Parameter& q) {
      return std::int64_t{c.u16(q.data.data())} + (std::int64_t{c.u16(q.data.data() + 2)} << 16);
    };
    n = field(*e) - field(*s) + 1;
  }
  if (const Parameter* f = find(p, "POINT:FRAMES")) {
    if (const auto v = f->number(c, true); v && *v > static_cast<double>(n)) {
      n = static_cast<std::int64_t>(*v);
    }
  }
  return std::max<std::int64_t>(n, 0);
}

Layout read_layout(int fd, std::int64_t size, const std::string& name) {
  unsigned char head[kBlock];
  if (!read_at(fd, 0, head, kBlock)) throw ConfigError(name, 0, "C3D: shorter than its header");
  const std::int64_t param_at = (std::int64_t{head[0]} - 1) * std::int64_t{kBlock};
  unsigned char ph[4];
  if (head[0] < 2 || !read_at(fd, param_at, ph, 4)) {
    throw ConfigError(name, 0, "C3D: no parameter section at block " + std::to_string(head[0]));
  }
  Layout L;
  if (ph[3] < 84 || ph[3] > 86) {
    throw ConfigError(name, 0,
                      "C3D: unknown processor type " + std::to_string(ph[3]) +
                          " (84 Intel, 85 DEC, 86 SGI/MIPS)");
  }
  L.codec.p = static_cast<Processor>(ph[3]);
  const Codec& c = L.codec;
  // Up to 255 blocks as the section says, within the file.
  const std::int64_t want = std::max<std::int64_t>(ph[2], 1) * std::int64_t{kBlock};
  const auto sec_bytes = static_cast<std::size_t>(std::min(want, size - param_at));
  std::vector<unsigned char> sec(sec_bytes);
  if (!read_at(fd, param_at, sec.data(), sec.size())) {
    throw ConfigError(name, 0, "C3D: cannot read the parameter section");
  }
  const Parameters p = parse_parameters(sec, c, name);
  L.points = c.u16(head + 2);
  if (const Parameter* u = find(p, "POINT:USED"))
    L.points = static_cast<std::size_t>(*u->number(c, true));
  L.analog_words = c.u16(head + 4);
  double scale = c.f32(head + 12);
  if (const Parameter* s = find(p, "POINT:SCALE"); s && s->number(c)) scale = *s->number(c);
  L.floats = scale < 0;
  L.scale = std::abs(scale);
  L.rate = c.f32(head + 20);
  if (const Parameter* r = find(p, "POINT:RATE"); r && r->number(c)) L.rate = *r->number(c);
  std::int64_t start_block = c.u16(head + 16);
  if (const Parameter* d = find(p, "POINT:DATA_START"); d && d->number(c, true)) {
    start_block = static_cast<std::int64_t>(*d->number(c, true));
  }
  L.data_start = (start_block - 1) * std::int64_t{kBlock};
  L.frames = frame_count(head, p, c);
  if (const Parameter* u = find(p, "POINT:UNITS")) {
    const auto s = u->strings();
    const std::string unit = s.empty() ? "mm" : upper(s[0]);
    if (unit == "M")
      L.to_m = 1.0;
    else if (unit == "CM")
      L.to_m = 1e-2;
    else if (unit == "MM" || unit.empty())
      L.to_m = 1e-3;
    else
      throw ConfigError(name, 0, "C3D: unknown POINT:UNITS '" + s[0] + "' (mm, cm or m)");
  }
  L.labels = point_labels(p, L.points);
  if (!(L.rate > 0)) throw ConfigError(name, 0, "C3D: no point frame rate (POINT:RATE)");
  if (L.points == 0) throw ConfigError(name, 0, "C3D: no 3-D points");
  if (start_block < 2)
    throw ConfigError(name, 0, "C3D: bad data start block " + std::to_string(start_block));
  if (!L.floats && !(L.scale > 0)) throw ConfigError(name, 0, "C3D: POINT:SCALE is 0");
  const std::int64_t need = L.data_start + L.frames * static_cast<std::int64_t>(L.frame_bytes());
  if (need > size) {
    throw ConfigError(name, 0,
                      "C3D: " + std::to_string(L.frames) + " frames of " +
                          std::to_string(L.frame_bytes()) + " bytes from byte " +
                          std::to_string(L.data_start) + " need " + std::to_string(need) +
                          " bytes; the file has " + std::to_string(size) + " (truncated?)");
  }
  return L;
}

// One point of a frame: x, y, z in m and whether it is valid.
bool decode_point(const Layout& L, const unsigned char* b, double xyz[3]) {
  const Codec& c = L.codec;
  double residual = 0;
  if (L.floats) {
    for (int k = 0; k < 3; ++k) xyz[k] = double(c.f32(b + 4 * k)) * L.to_m;
    residual = c.f32(b + 12);
  } else {
    for (int k = 0; k < 3; ++k) xyz[k] = double(c.i16(b + 2 * k)) * L.scale * L.to_m;
    residual = c.i16(b + 6);
  }
  return residual >= 0 && std::isfinite(xyz[0]) && std::isfinite(xyz[1]) && std::isfinite(xyz[2]);
}

}  // namespace

bool looks_like_c3d(const unsigned char* b, std::size_t n) noexcept {
  return n >= 4 && b[1] == kKey && b[0] >= 2;
}

MarkerSeries read_c3d(const std::string& path, const std::vector<MarkerRef>& wanted) {
  files::InputInfo info;
  int fd = -1;
  try {
    fd = files::open_input(path, files::kMaxCsvBytes, &info);
  } catch (const files::FileError& e) {
    throw ConfigError(path, 0, e.reason());
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  const Layout L = read_layout(fd, info.size, path);
  MarkerSeries out;
  out.source = path;
  out.info.format = MarkerFormat::kC3d;
  out.info.labels = L.labels;
  out.info.rate_hz = L.rate;
  out.info.epoch_times = false;
  out.ids = resolve_labels(L.labels, wanted, path);
  MarkerStore store;
  const std::size_t fb = L.frame_bytes();
  const std::size_t per_read =
      std::max<std::size_t>(1, (256 * 1024) / std::max<std::size_t>(fb, 1));
  std::vector<unsigned char> buf(per_read * fb);
  for (std::int64_t f0 = 0; f0 < L.frames; f0 += static_cast<std::int64_t>(per_read)) {
    const auto n = static_cast<std::size_t>(
        std::min<std::int64_t>(static_cast<std::int64_t>(per_read), L.frames - f0));
    if (!read_at(fd, L.data_start + f0 * static_cast<std::int64_t>(fb), buf.data(), n * fb)) {
      throw ConfigError(path, 0, "C3D: cannot read frame " + std::to_string(f0 + 1));
    }
    for (std::size_t k = 0; k < n; ++k) {
      const double t = static_cast<double>(f0 + static_cast<std::int64_t>(k)) / L.rate;
      for (int id : out.ids) {
        const std::size_t word = 4 * static_cast<std::size_t>(id - 1) * (L.floats ? 4 : 2);
        double xyz[3];
        MarkerSample s;
        s.utime_us = static_cast<std::int64_t>(std::llround(t * 1e6));
        s.marker_id = id;
        s.present = decode_point(L, buf.data() + k * fb + word, xyz);
        if (s.present) {
          s.x = xyz[0];
          s.y = xyz[1];
          s.z = xyz[2];
        }
        store.push(s);
      }
    }
  }
  out.thinned = store.thinned();
  out.samples = store.take();
  if (out.samples.empty()) throw ConfigError(path, 0, "C3D: no frames");
  return out;
}

}  // namespace exodaq::calibration::detail
