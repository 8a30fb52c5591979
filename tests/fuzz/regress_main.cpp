// Regular-build driver for the fuzz targets: runs one target's entry point
// on every file under the given files/directories (seed corpus and regression
// inputs), in name order. A finding aborts the process: the CTest test fails
// and names the file (printed before it is run). Every target is linked in;
// tests/fuzz/CMakeLists.txt renames each LLVMFuzzerTestOneInput() to
// exodaq_fuzz_<target> and lists them in fuzz_targets.inc.
//   fuzz_regress TARGET DIR_OR_FILE...
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#define EXODAQ_FUZZ_TARGET(t) extern "C" int exodaq_fuzz_##t(const std::uint8_t*, std::size_t);
#include "fuzz_targets.inc"
#undef EXODAQ_FUZZ_TARGET

namespace fs = std::filesystem;

namespace {

struct Target {
  const char* name;
  int (*run)(const std::uint8_t* data, std::size_t size);
};

constexpr Target kTargets[] = {
#define EXODAQ_FUZZ_TARGET(t) {#t, exodaq_fuzz_##t},
#include "fuzz_targets.inc"
#undef EXODAQ_FUZZ_TARGET
};

}  // namespace

int main(int argc, char** argv) {
  const Target* target = nullptr;
  for (const Target& t : kTargets) {
    if (argc > 1 && std::strcmp(argv[1], t.name) == 0) target = &t;
  }
  if (target == nullptr) {
    std::fprintf(stderr, "usage: fuzz_regress TARGET DIR_OR_FILE...; TARGET one of:");
    for (const Target& t : kTargets) std::fprintf(stderr, " %s", t.name);
    std::fprintf(stderr, "\n");
    return 2;
  }
  std::vector<fs::path> files;
  for (int i = 2; i < argc; ++i) {
    const fs::path p(argv[i]);
    if (fs::is_directory(p)) {
      for (const auto& e : fs::recursive_directory_iterator(p)) {
        const std::string name = e.path().filename().string();
        if (e.is_regular_file() && !name.empty() && name[0] != '.' && name != "README.md") {
          files.push_back(e.path());
        }
      }
    } else if (fs::is_regular_file(p)) {
      files.push_back(p);
    } else if (!fs::exists(p)) {
      std::fprintf(stderr, "%s: no such file or directory\n", argv[i]);
      return 2;
    }
  }
  std::sort(files.begin(), files.end());
  for (const auto& f : files) {
    std::fprintf(stderr, "running %s\n", f.string().c_str());
    std::ifstream in(f, std::ios::binary);
    const std::vector<char> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
    target->run(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
  }
  std::printf("%zu inputs ran without a finding\n", files.size());
  return 0;
}
