#pragma once
// Where the motion-capture markers of a calibration sit (docs/calibration.md
// §3.5): on the hand/forearm (the last link, DH frame 6) or on the
// exoskeleton's base (O0). Several markers make parameters identifiable that
// one marker cannot (§6). Errors are exodaq::ConfigError "file:line: what".
#include <array>
#include <string>
#include <vector>

namespace exodaq::calibration {

enum class MarkerMount {
  kHand,  // on the last link: frame 6, relative to the tool point; Δpᴹ is added
  kBase,  // on the exoskeleton's base: O0, the frame the daemon publishes in
};
const char* mount_name(MarkerMount m) noexcept;  // "hand", "base"

struct MarkerSite {
  int id = -1;  // marker_id in the mocap CSV (-1: the file has no marker_id column)
  MarkerMount mount = MarkerMount::kHand;
  std::array<double, 3> position{};  // m, in the mount's frame (above)
  std::string label{};               // its label in a labelled export (C3D, Vicon, Motive)
  std::string name() const { return label.empty() ? std::to_string(id) : label; }
};

// The markers of one calibration. Without a layout file, every marker sample
// is the one hand marker of seed 000 at the tool point.
struct MarkerLayout {
  std::string source;
  std::vector<MarkerSite> sites;  // at least one hand marker; ids and labels unique

  const MarkerSite* find(int id) const noexcept;
  std::vector<int> ids() const;
  std::vector<int> ids(MarkerMount mount) const;
};

struct MarkerRef;
struct MarkerSeries;
// The sites as references for read_markers (MarkerRef: id and label).
std::vector<MarkerRef> layout_refs(const MarkerLayout& layout);
// The layout with each site's id set to what its reference resolved to in
// `series` (MarkerSeries::ids, in the order of layout_refs).
MarkerLayout resolved_layout(const MarkerLayout& layout, const MarkerSeries& series);

// YAML, `format: exodaq-marker-layout-1` (config/calibration/markers_example.yaml):
// each marker has an `id`, a `label` or both.
MarkerLayout load_marker_layout_file(const std::string& path);
MarkerLayout load_marker_layout_text(const std::string& text, const std::string& name);

}  // namespace exodaq::calibration
