#include "exodaq/calibration/marker_layout.hpp"

#include <algorithm>

#include "exodaq/calibration/inputs.hpp"
#include "exodaq/common/yaml_reader.hpp"

namespace exodaq::calibration {

namespace {

MarkerSite read_site(const std::string& file, const YAML::Node& node, std::size_t index) {
  exodaq::MapReader m(file, node, "markers[" + std::to_string(index) + "]");
  MarkerSite s;
  if (!m.has("id") && !m.has("label")) {
    m.fail(m.node(), "a marker needs an 'id' (long CSV), a 'label' (C3D, Vicon, Motive) or both");
  }
  if (m.has("id")) {
    const std::int64_t id = m.integer("id");
    if (id < 0 || id > 1'000'000'000) m.fail(m.child("id"), "'id' must be a marker_id >= 0");
    s.id = static_cast<int>(id);
  }
  if (m.has("label")) {
    s.label = m.string("label");
    if (s.label.empty()) m.fail(m.child("label"), "'label' must not be empty");
  }
  s.mount = m.choice("on", {"hand", "base"}) == "hand" ? MarkerMount::kHand : MarkerMount::kBase;
  const auto mm = m.numbers_fixed<3>("position_mm");
  for (int k = 0; k < 3; ++k) s.position[k] = mm[k] * 1e-3;
  m.finish();
  return s;
}

MarkerLayout parse_layout(const YAML::Node& root, const std::string& file) {
  exodaq::MapReader top(file, root, "marker layout");
  const YAML::Node format = top.child("format");
  if (!format.IsScalar() || format.Scalar() != "exodaq-marker-layout-1") {
    top.fail(format, "'format' must be 'exodaq-marker-layout-1'");
  }
  const YAML::Node list = top.child("markers");
  if (!list.IsSequence() || list.size() == 0) top.fail(list, "'markers' must be a non-empty list");
  MarkerLayout layout;
  layout.source = file;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const MarkerSite s = read_site(file, list[i], i);
    for (const MarkerSite& o : layout.sites) {
      if (s.id >= 0 && o.id == s.id) {
        top.fail(list[i], "marker id " + std::to_string(s.id) + " appears twice");
      }
      if (!s.label.empty() && o.label == s.label) {
        top.fail(list[i], "marker label '" + s.label + "' appears twice");
      }
    }
    layout.sites.push_back(s);
  }
  if (layout.ids(MarkerMount::kHand).empty()) {
    top.fail(list, "at least one marker must be 'on: hand' (the base markers see no joint)");
  }
  top.finish();
  return layout;
}

}  // namespace

const char* mount_name(MarkerMount m) noexcept {
  return m == MarkerMount::kHand ? "hand" : "base";
}

const MarkerSite* MarkerLayout::find(int id) const noexcept {
  const auto it =
      std::find_if(sites.begin(), sites.end(), [id](const MarkerSite& s) { return s.id == id; });
  return it == sites.end() ? nullptr : &*it;
}

std::vector<int> MarkerLayout::ids() const {
  std::vector<int> out;
  for (const auto& s : sites) out.push_back(s.id);
  return out;
}

std::vector<int> MarkerLayout::ids(MarkerMount mount) const {
  std::vector<int> out;
  for (const auto& s : sites) {
    if (s.mount == mount) out.push_back(s.id);
  }
  return out;
}

std::vector<MarkerRef> layout_refs(const MarkerLayout& layout) {
  std::vector<MarkerRef> refs;
  for (const auto& s : layout.sites) refs.push_back(MarkerRef{s.id, s.label});
  return refs;
}

MarkerLayout resolved_layout(const MarkerLayout& layout, const MarkerSeries& series) {
  MarkerLayout out = layout;
  for (std::size_t k = 0; k < out.sites.size() && k < series.ids.size(); ++k) {
    out.sites[k].id = series.ids[k];
  }
  return out;
}

MarkerLayout load_marker_layout_file(const std::string& path) {
  return parse_layout(exodaq::load_yaml_file(path), path);
}

MarkerLayout load_marker_layout_text(const std::string& text, const std::string& name) {
  return parse_layout(exodaq::load_yaml_text(text, name), name);
}

}  // namespace exodaq::calibration
