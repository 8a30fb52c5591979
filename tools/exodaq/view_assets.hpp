#pragma once
// The web page of `exodaq view` (tools/view/web/), built into the binary at
// build time (tools/view/CMakeLists.txt): nothing is read from disk or fetched
// at run time.
#include <span>
#include <string_view>

namespace exodaq::tools::view {

struct WebAsset {
  std::string_view path;          // "/index.html", "/view.js", ...
  std::string_view content_type;  // "text/html; charset=utf-8", ...
  std::string_view body;
};

std::span<const WebAsset> web_assets();

}  // namespace exodaq::tools::view
