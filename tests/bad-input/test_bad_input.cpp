// The bad-input catalogue (docs/robustness.md "Bad input"): every file under
// tests/bad-input/<kind>/ is a malformed input with the exact message(s) it
// must produce in <file>.expected (one per line, `file:line: what`; for LCM
// logs the "line" is the event number, as exodaq replay prints it). Each is
// checked through the real loader and through the tool a user would run:
//   models        load_model_file        and  exodaq fk --model FILE
//   calibrations  load_calibration_file  and  exodaqd --check-config (a config naming it)
//   configs       load_service_config    and  exodaqd --config FILE --check-config
//   candump       ReplaySource (candump) and  exodaq replay FILE
//   lcm           ReplaySource (lcm)     and  exodaq replay FILE
// Files are named relative to their folder (the test runs there), so the
// messages are the same on every machine.
// EXODAQ_BAD_INPUT_PRINT=1 prints what each input gives instead of checking
// (for writing a new case's .expected; read it before you accept it).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "exodaq/drivers/replay_source.hpp"
#include "exodaq/settings/calibration_file.hpp"
#include "exodaq/settings/model_file.hpp"
#include "exodaq/settings/service_config.hpp"
#include "process.hpp"
#include "sim_daemon.hpp"

namespace fs = std::filesystem;

namespace {

const std::string kRoot = std::string(EXODAQ_SOURCE_DIR) + "/tests/bad-input";

struct Case {
  std::string kind;  // folder
  std::string file;  // name inside it
};

void PrintTo(const Case& c, std::ostream* os) {
  *os << c.kind << "/" << c.file;
}

std::vector<Case> all_cases() {
  std::vector<Case> out;
  for (const char* kind : {"models", "calibrations", "configs", "candump", "lcm"}) {
    const fs::path dir = fs::path(kRoot) / kind;
    if (!fs::is_directory(dir)) continue;
    for (const auto& e : fs::directory_iterator(dir)) {
      const std::string name = e.path().filename().string();
      if (e.path().extension() == ".expected" || name == "README.md" || name[0] == '.') continue;
      out.push_back({kind, name});
    }
  }
  std::sort(out.begin(), out.end(),
            [](const Case& a, const Case& b) { return a.kind + a.file < b.kind + b.file; });
  return out;
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) out.push_back(line);
  return out;
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& l : v) s += l + "\n";
  return s;
}

// What the library says about the input: the exception text, or the issues
// of a replay that loaded (one per line).
std::vector<std::string> library_messages(const Case& c) {
  try {
    if (c.kind == "models") {
      (void)exodaq::settings::load_model_file(c.file);
    } else if (c.kind == "calibrations") {
      (void)exodaq::settings::load_calibration_file(c.file);
    } else if (c.kind == "configs") {
      (void)exodaq::settings::load_service_config(c.file);
    } else {
      exodaq::drivers::ReplaySettings settings;
      settings.path = c.file;
      settings.format = c.kind;
      exodaq::drivers::ReplaySource source(settings, exodaq::drivers::SourceContext{});
      source.start();
      std::vector<std::string> out;
      for (const auto& issue : source.issues()) {
        out.push_back(c.file + ":" + std::to_string(issue.line) + ": " + issue.what);
      }
      return out;
    }
  } catch (const exodaq::ConfigError& e) {
    return {e.what()};
  } catch (const std::runtime_error& e) {
    return {e.what()};
  }
  return {};
}

std::string sim_config() {
  return std::string(EXODAQ_SOURCE_DIR) + "/config/sim.yaml";
}

// The tool a user would run on the input: exit code and stderr.
exodaq::test::RunResult run_tool(const Case& c, const std::string& tmp) {
  if (c.kind == "models") {
    return exodaq::test::run({EXODAQ_TOOL, "fk", "--model", c.file, "--joints-deg", "0,0,0,0,0,0"});
  }
  if (c.kind == "configs") {
    return exodaq::test::run({EXODAQD, "--config", c.file, "--check-config"});
  }
  if (c.kind == "calibrations") {
    // The sim config naming this calibration by its absolute path (the
    // message then names that path), written to the temporary directory.
    const std::string path =
        exodaq::test::write_sim_config(tmp, "BADINPUT_", kRoot + "/calibrations/" + c.file);
    return exodaq::test::run({EXODAQD, "--config", path, "--check-config"});
  }
  return exodaq::test::run({EXODAQ_TOOL, "replay", c.file, "-c", sim_config(), "--format", c.kind,
                            "-o", tmp + "/out.lcm", "-q"});
}

class BadInput : public ::testing::TestWithParam<Case> {
 protected:
  void SetUp() override {
    previous_ = fs::current_path();
    fs::current_path(fs::path(kRoot) / GetParam().kind);
  }
  void TearDown() override { fs::current_path(previous_); }

 private:
  fs::path previous_;
};

TEST_P(BadInput, LoaderAndToolGiveTheExactMessage) {
  const Case& c = GetParam();
  const std::vector<std::string> got = library_messages(c);
  const std::string tmp = exodaq::test::make_temp_dir("badinput");
  if (std::getenv("EXODAQ_BAD_INPUT_PRINT") != nullptr) {
    const auto r = run_tool(c, tmp);
    std::printf("=== %s/%s\n%s--- tool (exit %d):\n%s", c.kind.c_str(), c.file.c_str(),
                join(got).c_str(), r.exit_code, r.err.c_str());
    return;
  }
  const fs::path expected_file = c.file + ".expected";
  ASSERT_TRUE(fs::exists(expected_file)) << "no " << expected_file << " for " << c.file;
  const std::vector<std::string> expected = lines_of(read_text(expected_file));
  ASSERT_FALSE(expected.empty()) << expected_file << " is empty";

  // 1. The library, exactly.
  EXPECT_EQ(join(got), join(expected));

  // 2. The tool: a failure exit code for a rejected input, and every message
  // on stderr as the tool prints it.
  const auto r = run_tool(c, tmp);
  const bool loaded = c.kind == "candump" || c.kind == "lcm";
  bool replayed = false;
  if (loaded) {
    // A replay that loads reports its issues and exits 1 (0 when they are
    // only notes: another daemon run in the log); one that cannot load exits
    // 2 with the error.
    replayed = r.exit_code != 2;
    if (replayed) {
      const bool notes_only = std::all_of(expected.begin(), expected.end(), [](const auto& l) {
        return l.find("the log holds another daemon run") != std::string::npos;
      });
      EXPECT_EQ(r.exit_code, notes_only ? 0 : 1) << r.err;
    }
  } else if (c.kind == "models") {
    EXPECT_EQ(r.exit_code, 2) << r.err;
  } else {
    EXPECT_EQ(r.exit_code, 1) << r.err;
  }
  for (const auto& line : expected) {
    std::string shown;
    if (c.kind == "models") {
      shown = "exodaq fk: " + line + "\n";
    } else if (c.kind == "configs") {
      shown = "exodaqd: " + line + "\n";
    } else if (c.kind == "calibrations") {
      shown = "exodaqd: " + kRoot + "/calibrations/" + line + "\n";
    } else if (replayed) {
      shown = "  " + line + "\n";
    } else {
      // The tool's error line: "exodaq replay: <what>", without the
      // backend's own "replay: ".
      const std::string what = line.rfind("replay: ", 0) == 0 ? line.substr(8) : line;
      shown = "exodaq replay: " + what + "\n";
    }
    EXPECT_NE(r.err.find(shown), std::string::npos)
        << "expected on stderr: " << shown << "stderr:\n"
        << r.err;
  }
}

INSTANTIATE_TEST_SUITE_P(Catalogue, BadInput, ::testing::ValuesIn(all_cases()),
                         [](const auto& info) {
                           std::string n = info.param.kind + "_" + info.param.file;
                           for (char& ch : n) {
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           }
                           return n;
                         });

TEST(BadInputCatalogue, HoldsAtLeastFortyInputsEachWithItsMessage) {
  const auto cases = all_cases();
  EXPECT_GE(cases.size(), 40u);
  for (const auto& c : cases) {
    EXPECT_TRUE(fs::exists(fs::path(kRoot) / c.kind / (c.file + ".expected")))
        << c.kind << "/" << c.file;
  }
}

}  // namespace
