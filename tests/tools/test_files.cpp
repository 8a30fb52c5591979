// Issue 15 points 6 and 7: output files written safely and input files
// checked before reading, in every tool. First common/files.hpp itself, then
// each reproduction of the issue with the real programs (exodaqd, exodaq).
// Needs root for the tmpfs "full filesystem" and the device nodes (skipped
// otherwise, saying so).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <future>
#include <sstream>
#include <string>
#include <vector>

#include "exodaq/common/files.hpp"
#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/raw_sample.hpp"
#include "exodaq/settings/service_config.hpp"
#include "process.hpp"
#include "sim_daemon.hpp"

namespace exodaq {
namespace {

namespace fs = std::filesystem;
using files::FileError;

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// Names starting with '.' in `dir`: a temporary file left behind.
int hidden_files(const std::string& dir) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir)) n += e.path().filename().string()[0] == '.';
  return n;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const FileError& e) {
    return e.what();
  }
  return "no error";
}

// A 64 KiB tmpfs, full to the last byte but for `keep` bytes of files made
// first; unmounted at the end. Empty path: not root.
class FullFilesystem {
 public:
  explicit FullFilesystem(const std::string& dir) : dir_(dir) {
    fs::create_directories(dir_);
    if (::mount("tmpfs", dir_.c_str(), "tmpfs", 0, "size=64k") != 0) dir_.clear();
  }
  void fill() const {
    std::ofstream f(dir_ + "/filler", std::ios::binary);
    const std::string block(4096, 'x');
    for (int i = 0; i < 40 && f; ++i) f << block;
  }
  ~FullFilesystem() {
    if (!dir_.empty()) ::umount(dir_.c_str());
  }
  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
};

class Files : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::make_temp_dir("files"); }
  std::string dir_;
};

// --- outputs -----------------------------------------------------------------

TEST_F(Files, AnOutputAppearsOnlyWhenCommitted) {
  const std::string path = dir_ + "/out.csv";
  {
    files::OutputFile out(path);
    out.write("a,b\n");
    out.flush();
    EXPECT_FALSE(fs::exists(path));
    EXPECT_EQ(hidden_files(dir_), 1);  // the temporary file beside it
    out.commit();
  }
  EXPECT_EQ(read_text(path), "a,b\n");
  EXPECT_EQ(hidden_files(dir_), 0);
  {
    files::OutputFile out(path);
    out.write("half a fi");
  }  // not committed: the old file stays, the temporary file goes
  EXPECT_EQ(read_text(path), "a,b\n");
  EXPECT_EQ(hidden_files(dir_), 0);
}

TEST_F(Files, ASymlinkIsFollowedAndKept) {
  fs::create_directories(dir_ + "/cal");
  write_text(dir_ + "/cal/rig-2026-11.yaml", "old\n");
  fs::create_symlink("cal/rig-2026-11.yaml", dir_ + "/current.yaml");
  fs::create_symlink("current.yaml", dir_ + "/link-to-link.yaml");
  files::write_output(dir_ + "/link-to-link.yaml", "new\n");
  EXPECT_TRUE(fs::is_symlink(dir_ + "/current.yaml"));
  EXPECT_TRUE(fs::is_symlink(dir_ + "/link-to-link.yaml"));
  EXPECT_EQ(read_text(dir_ + "/cal/rig-2026-11.yaml"), "new\n");
  EXPECT_EQ(hidden_files(dir_ + "/cal"), 0);
  // A dangling link: the file it names is created, the link kept.
  fs::create_symlink("cal/next.yaml", dir_ + "/next-link.yaml");
  files::write_output(dir_ + "/next-link.yaml", "next\n");
  EXPECT_TRUE(fs::is_symlink(dir_ + "/next-link.yaml"));
  EXPECT_EQ(read_text(dir_ + "/cal/next.yaml"), "next\n");
}

TEST_F(Files, ModeIsKeptOrTakenFromTheUmask) {
  write_text(dir_ + "/private.yaml", "x");
  fs::permissions(dir_ + "/private.yaml", fs::perms(0600));
  files::write_output(dir_ + "/private.yaml", "y");
  EXPECT_EQ(fs::status(dir_ + "/private.yaml").permissions(), fs::perms(0600));
  const mode_t old = ::umask(022);
  files::write_output(dir_ + "/new.yaml", "z");
  ::umask(old);
  EXPECT_EQ(fs::status(dir_ + "/new.yaml").permissions(), fs::perms(0644));
}

TEST_F(Files, OnlyRegularFilesAreReplaced) {
  fs::create_directories(dir_ + "/folder");
  EXPECT_EQ(
      error_of([&] { files::OutputFile o(dir_ + "/folder"); }),
      dir_ + "/folder: is a directory, not a regular file: not replaced (name a file to write)");
  ASSERT_EQ(::mkfifo((dir_ + "/fifo").c_str(), 0600), 0);
  EXPECT_EQ(error_of([&] { files::OutputFile o(dir_ + "/fifo"); }),
            dir_ + "/fifo: is a FIFO, not a regular file: not replaced (name a file to write)");
  // Checked without writing anything, so /dev/null itself is safe to name.
  EXPECT_EQ(error_of([&] { files::check_output("/dev/null"); }),
            "/dev/null: is a character device, not a regular file: not replaced (name a file to "
            "write)");
  fs::create_symlink("/dev/null", dir_ + "/null-link");
  EXPECT_NE(error_of([&] {
              files::OutputFile o(dir_ + "/null-link");
            }).find("is a character device (the target of the link, '/dev/null')"),
            std::string::npos);
  EXPECT_EQ(error_of([&] { files::OutputFile o(dir_ + "/no/such/folder/x.csv"); }),
            dir_ + "/no/such/folder/x.csv: cannot write into '" + dir_ +
                "/no/such/folder': No such file or directory");
  EXPECT_EQ(error_of([&] { files::OutputFile o("-"); }),
            "-: this output cannot go to standard output: name a file");
  EXPECT_EQ(hidden_files(dir_), 0);
}

TEST_F(Files, AnInputIsNeverAnOutput) {
  write_text(dir_ + "/in.lcm", "recording");
  ::link((dir_ + "/in.lcm").c_str(), (dir_ + "/hard.lcm").c_str());
  fs::create_symlink("in.lcm", dir_ + "/soft.lcm");
  files::OutputOptions o;
  o.inputs = {dir_ + "/soft.lcm"};
  for (const char* out : {"/in.lcm", "/hard.lcm", "/soft.lcm"}) {
    EXPECT_NE(error_of([&] { files::OutputFile f(dir_ + out, o); }).find("is also an input"),
              std::string::npos)
        << out;
  }
  EXPECT_EQ(read_text(dir_ + "/in.lcm"), "recording");
}

// Issue 25 point 6: a link is followed only when the caller, or root in a
// folder of the caller's or root's, made it (fs.protected_symlinks, checked
// here whatever the sysctl says: it is 0 in containers). The other user is a
// bare uid given to the link with lchown (needs root).
constexpr uid_t kOtherUid = 4242;

TEST_F(Files, ALinkOfAnotherUserIsNotFollowedAndNothingIsWritten) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root to give a link to another uid";
  write_text(dir_ + "/victim.conf", "root's\n");
  const std::string shared = dir_ + "/shared";  // like /tmp: sticky, world-writable
  fs::create_directories(shared);
  ASSERT_EQ(::chmod(shared.c_str(), 01777), 0);
  fs::create_symlink(dir_ + "/victim.conf", shared + "/out.csv");
  ASSERT_EQ(::lchown((shared + "/out.csv").c_str(), kOtherUid, kOtherUid), 0);
  const std::string e = error_of([&] { files::write_output(shared + "/out.csv", "export\n"); });
  EXPECT_EQ(e, shared + "/out.csv: '" + shared +
                   "/out.csv' is a symbolic link of uid 4242 in a "
                   "sticky folder of uid 0 ('root'): not followed "
                   "(another user could have planted it; name the "
                   "file it points to, or write elsewhere)");
  EXPECT_EQ(error_of([&] { files::check_output(shared + "/out.csv"); }), e);
  EXPECT_EQ(read_text(dir_ + "/victim.conf"), "root's\n");
  EXPECT_EQ(hidden_files(shared), 0);

  // A folder on the way that is such a link: the same.
  fs::create_directories(dir_ + "/private");
  fs::create_symlink(dir_ + "/private", shared + "/sub");
  ASSERT_EQ(::lchown((shared + "/sub").c_str(), kOtherUid, kOtherUid), 0);
  EXPECT_NE(error_of([&] {
              files::write_output(shared + "/sub/out.csv", "x");
            }).find("'" + shared + "/sub' is a symbolic link of uid 4242"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(dir_ + "/private/out.csv"));

  // A folder of another user's, not sticky: their link is not followed either.
  const std::string theirs = dir_ + "/theirs";
  fs::create_directories(theirs);
  fs::create_symlink(dir_ + "/victim.conf", theirs + "/out.csv");
  ASSERT_EQ(::lchown((theirs + "/out.csv").c_str(), kOtherUid, kOtherUid), 0);
  ASSERT_EQ(::chown(theirs.c_str(), kOtherUid, kOtherUid), 0);
  EXPECT_NE(error_of([&] {
              files::write_output(theirs + "/out.csv", "x");
            }).find("is a symbolic link of uid 4242 in a folder of uid 4242: not followed"),
            std::string::npos);
  EXPECT_EQ(read_text(dir_ + "/victim.conf"), "root's\n");
}

TEST_F(Files, TheCallersOwnLinksAreFollowedInAStickyFolder) {
  const std::string shared = dir_ + "/shared";
  fs::create_directories(shared + "/../data");
  ASSERT_EQ(::chmod(shared.c_str(), 01777), 0);
  write_text(dir_ + "/data/out.csv", "old\n");
  fs::create_symlink("../data/out.csv", shared + "/out.csv");
  fs::create_symlink("../data", shared + "/data-link");
  files::write_output(shared + "/out.csv", "new\n");
  EXPECT_TRUE(fs::is_symlink(shared + "/out.csv"));
  EXPECT_EQ(read_text(dir_ + "/data/out.csv"), "new\n");
  files::write_output(shared + "/data-link/second.csv", "2\n");
  EXPECT_EQ(read_text(dir_ + "/data/second.csv"), "2\n");
  // A name that is not a file to write.
  EXPECT_EQ(error_of([&] { files::check_output(shared + "/"); }),
            shared + "/: ends with '/': name a file to write");
  EXPECT_EQ(error_of([&] { files::check_output("/"); }),
            "/: is a directory, not a regular file: not replaced (name a file to write)");
}

TEST_F(Files, AFullFilesystemIsAnErrorWithTheReasonAndLeavesNothing) {
  const FullFilesystem full(dir_ + "/full");
  if (full.dir().empty()) GTEST_SKIP() << "cannot mount a tmpfs (needs root)";
  write_text(full.dir() + "/old.csv", "old\n");
  const std::string chunk(10'000, 'x');
  const std::string e = error_of([&] {
    files::OutputFile out(full.dir() + "/old.csv");
    for (int i = 0; i < 20; ++i) out.write(chunk);
    out.commit();
  });
  EXPECT_EQ(e, full.dir() + "/old.csv: cannot write: No space left on device");
  EXPECT_EQ(read_text(full.dir() + "/old.csv"), "old\n");
  EXPECT_EQ(hidden_files(full.dir()), 0);
}

// --- inputs ------------------------------------------------------------------

TEST_F(Files, InputsAreCheckedBeforeReading) {
  ASSERT_EQ(::mkfifo((dir_ + "/fifo.yaml").c_str(), 0600), 0);
  // Refused without blocking: an open() that waited for a writer would never
  // return; then a writer is opened here to release it, and the test fails.
  auto refused = std::async(std::launch::async, [&] {
    return error_of([&] { files::read_input(dir_ + "/fifo.yaml", 100); });
  });
  if (refused.wait_for(std::chrono::seconds(60)) != std::future_status::ready) {
    const int writer = ::open((dir_ + "/fifo.yaml").c_str(), O_WRONLY | O_NONBLOCK);
    refused.wait();
    ::close(writer);
    FAIL() << "read_input blocked on a FIFO";
  }
  EXPECT_EQ(refused.get(), dir_ + "/fifo.yaml: is a FIFO, not a regular file");
  EXPECT_EQ(error_of([&] { files::read_input("/dev/zero", 100); }),
            "/dev/zero: is a character device, not a regular file");
  EXPECT_EQ(error_of([&] { files::read_input(dir_, 100); }),
            dir_ + ": is a directory, not a regular file");
  // Over the limit: refused from the size alone (a sparse file of 5 MiB).
  ::truncate((dir_ + "/big.yaml").c_str(), 0);
  write_text(dir_ + "/big.yaml", "");
  ASSERT_EQ(::truncate((dir_ + "/big.yaml").c_str(), 5 << 20), 0);
  EXPECT_EQ(error_of([&] { files::read_input(dir_ + "/big.yaml", files::kMaxYamlBytes); }),
            dir_ + "/big.yaml: is 5242880 bytes, more than the 4194304-byte limit for this input");
  write_text(dir_ + "/ok.yaml", "rig: a\n");
  EXPECT_EQ(files::read_input(dir_ + "/ok.yaml", files::kMaxYamlBytes), "rig: a\n");
}

TEST(FilesText, NulAndInvalidUtf8AreFoundWithTheirLine) {
  using files::find_text_problem;
  EXPECT_FALSE(
      find_text_problem("rig: bench\nname: \xc3\xa9t\xc3\xa9 \xe2\x82\xac \xf0\x9d\x84\x9e\n"));
  const auto at = [](std::string_view t) {
    const auto p = find_text_problem(t);
    return p ? std::to_string(p->line) + ": " + p->what_and_column() : std::string("clean");
  };
  EXPECT_EQ(at(std::string_view("a: 1\nb: 2\0 3\n", 12)),
            "2: NUL byte (a binary file?) at column 5");
  EXPECT_EQ(at("a: 1\nrig: b\xffnch\n"), "2: invalid UTF-8 (byte 0xff) at column 7");
  EXPECT_EQ(at("x: \xc0\x80\n"), "1: invalid UTF-8 (byte 0xc0) at column 4");  // overlong
  EXPECT_EQ(at("x: \xed\xa0\x80\n"),
            "1: invalid UTF-8 (byte 0xed starts a broken sequence) at column 4");  // surrogate
  EXPECT_EQ(at("x: \xe2\x82"), "1: invalid UTF-8 (byte 0xe2 starts a broken sequence) at column 4");
}

TEST(FilesText, ClosestMatchSuggestsOnlyLikelyMisspellings) {
  const std::vector<std::string> opts{"--config", "--out", "--quiet", "--verbose", "--prefix"};
  EXPECT_EQ(files::closest_match("--quite", opts), "--quiet");
  EXPECT_EQ(files::closest_match("--confg", opts), "--config");
  EXPECT_EQ(files::closest_match("--output", opts), "--out");
  EXPECT_EQ(files::closest_match("--csv", opts), "");
  EXPECT_EQ(files::closest_match("rigg", {"rig", "loop"}), "rig");
  EXPECT_EQ(files::closest_match("speed", {"rig", "loop"}), "");
}

// --- the tools, as real processes ---------------------------------------------

// A log with every channel: the sim's raw samples (as bench_replay_gen
// writes them) run through `exodaq replay`.
struct Recording {
  std::string dir, config, raw, log;
};
Recording* g_rec = nullptr;

class ToolFiles : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    auto* r = new Recording;
    r->dir = test::make_temp_dir("tool-files");
    r->config = test::write_sim_config(r->dir, "");
    const settings::ServiceConfig cfg = settings::load_service_config(r->config);
    const auto ctx = settings::make_source_context(cfg);
    drivers::sim::SimOptions opt = drivers::sim_options_from(cfg.source, ctx);
    opt.start_mono_ns = 1'000'000'000;
    opt.wall_offset_ns = 1'700'000'000'000'000'000LL;
    drivers::SimSource sim(opt);
    sim.start();
    r->raw = r->dir + "/raw.lcm";
    messages::LogWriter log(r->raw);
    encoder_raw_t raw{};
    raw.run_id = 0x5eed;
    std::vector<std::uint8_t> buf(4096);
    drivers::EncoderSample s;
    for (std::int64_t k = 0; k < 3000; ++k) {
      drivers::CycleTime t;
      t.cycle = k;
      sim.read(t, s);
      raw.utime = s.wall_ns / 1000;
      raw.mono_ns = s.mono_ns;
      raw.seq = k;
      messages::to_encoder_raw(s, raw);
      const int n = raw.encode(buf.data(), 0, static_cast<int>(buf.size()));
      log.write("EXO_ENCODER_RAW", raw.utime, buf.data(), static_cast<std::size_t>(n));
    }
    log.close();
    r->log = r->dir + "/all.lcm";
    const auto res =
        test::run({EXODAQ_TOOL, "replay", r->raw, "-c", r->config, "-o", r->log, "-q"});
    ASSERT_EQ(res.exit_code, 0) << res.err;
    g_rec = r;
  }
  static void TearDownTestSuite() {
    delete g_rec;
    g_rec = nullptr;
  }
  void SetUp() override {
    ASSERT_NE(g_rec, nullptr) << "the recording could not be made (SetUpTestSuite)";
    dir_ = test::make_temp_dir("tool-files-case");
  }
  // Runs a shell line (for redirections); returns exit code and stderr.
  static test::RunResult sh(const std::string& line) {
    return test::run({"/bin/sh", "-c", line}, std::chrono::seconds(60));
  }
  std::string dir_;
};

const std::string kTool = EXODAQ_TOOL;

TEST_F(ToolFiles, ExportToAFullDeviceOrClosedStdoutFailsWithTheReason) {
  auto r = sh(kTool + " export " + g_rec->log + " -q > /dev/full");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.err, "exodaq export: standard output: cannot write: No space left on device\n");
  r = sh(kTool + " export " + g_rec->log + " -q >&-");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.err, "exodaq export: standard output: cannot write: Bad file descriptor\n");
  r = sh(kTool + " fk --joints-deg 0,0,0,0,0,0 > /dev/full");  // stdio output too
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.err, "exodaq fk: cannot write to standard output: No space left on device\n");
  r = sh(kTool + " export " + g_rec->log + " -o /dev/full");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("/dev/full: is a character device, not a regular file: not replaced"),
            std::string::npos)
      << r.err;
}

TEST_F(ToolFiles, OutputsOnAFullFilesystemLeaveNothing) {
  const FullFilesystem full(dir_ + "/full");
  if (full.dir().empty()) GTEST_SKIP() << "cannot mount a tmpfs (needs root)";
  full.fill();
  const std::string d = full.dir();
  auto r = test::run({EXODAQ_TOOL, "export", g_rec->log, "-o", d + "/cycles.csv"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "exodaq export: " + d + "/cycles.csv: cannot write: No space left on device\n");
  r = test::run({EXODAQ_TOOL, "replay", g_rec->raw, "-c", g_rec->config, "-o", d + "/r.lcm", "-q"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "exodaq replay: " + d + "/r.lcm: cannot write: No space left on device\n");
  // Plot: the folder exists (on the full disk); no PNG, no traceback.
  r = test::run({EXODAQ_TOOL, "plot", g_rec->log, "-o", d, "-q"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("cannot write: No space left on device"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("Traceback"), std::string::npos) << r.err;
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(d)) left.push_back(e.path().filename().string());
  EXPECT_EQ(left, std::vector<std::string>{"filler"});
}

// Issue 25 point 6, as it was found: in a sticky world-writable folder,
// another user (a process of uid 4242) plants out.csv -> a file of root's;
// root's `exodaq export -o folder/out.csv` refuses and the file stays.
TEST_F(ToolFiles, ExportAsRootThroughALinkPlantedByAnotherUserIsRefused) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root (the export runs as root, the planter not)";
  ASSERT_EQ(::chmod(dir_.c_str(), 0755), 0);
  write_text(dir_ + "/victim.conf", "root's\n");
  ASSERT_EQ(::chmod((dir_ + "/victim.conf").c_str(), 0644), 0);
  const std::string shared = dir_ + "/shared";
  fs::create_directories(shared);
  ASSERT_EQ(::chmod(shared.c_str(), 01777), 0);
  const auto plant = test::run({"setpriv", "--reuid=4242", "--regid=4242", "--clear-groups", "ln",
                                "-s", dir_ + "/victim.conf", shared + "/out.csv"});
  ASSERT_EQ(plant.exit_code, 0) << plant.err;
  struct stat st {};
  ASSERT_EQ(::lstat((shared + "/out.csv").c_str(), &st), 0);
  ASSERT_EQ(st.st_uid, kOtherUid);

  const auto r = test::run({EXODAQ_TOOL, "export", g_rec->log, "-o", shared + "/out.csv"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "exodaq export: " + shared + "/out.csv: '" + shared +
                       "/out.csv' is a symbolic link of uid 4242 in a sticky folder of uid 0 "
                       "('root'): not followed (another user could have planted it; name the "
                       "file it points to, or write elsewhere)\n");
  EXPECT_EQ(read_text(dir_ + "/victim.conf"), "root's\n");
  EXPECT_EQ(hidden_files(shared), 0);
  // Named directly, root's file is written as asked.
  const auto direct = test::run({EXODAQ_TOOL, "export", g_rec->log, "-o", dir_ + "/victim.conf"});
  EXPECT_EQ(direct.exit_code, 0) << direct.err;
  EXPECT_EQ(read_text(dir_ + "/victim.conf").rfind("utime", 0), 0u);
}

TEST_F(ToolFiles, AnOutputEqualToAnInputIsRefusedBeforeAnythingIsWritten) {
  const std::string copy = dir_ + "/raw.lcm";
  fs::copy_file(g_rec->raw, copy);
  const std::string before = read_text(copy);
  auto r = test::run({EXODAQ_TOOL, "replay", copy, "-c", g_rec->config, "-o", copy});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("exodaq replay: " + copy + ": is also an input"), std::string::npos)
      << r.err;
  r = test::run({EXODAQ_TOOL, "export", copy, "-o", copy});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(read_text(copy), before);
  EXPECT_EQ(hidden_files(dir_), 0);
}

TEST_F(ToolFiles, BadInputsSayWhatTheFileIsAndCreateNoOutput) {
  write_text(dir_ + "/cycles.csv", "utime_us,seq\n1,2\n");
  write_text(dir_ + "/empty.lcm", "");
  ASSERT_EQ(::mkfifo((dir_ + "/fifo.lcm").c_str(), 0600), 0);
  struct Case {
    std::vector<std::string> args;
    std::string err;
  };
  const std::string out = dir_ + "/never";
  const std::vector<Case> cases{
      {{"export", dir_ + "/cycles.csv", "-o", out},
       "exodaq export: " + dir_ +
           "/cycles.csv: not an LCM log (first bytes 75 74 69 6d 65 5f 75 73)\n"},
      {{"export", dir_ + "/empty.lcm", "-o", out},
       "exodaq export: " + dir_ + "/empty.lcm: empty file, not an LCM log\n"},
      {{"export", dir_ + "/fifo.lcm", "-o", out},
       "exodaq export: " + dir_ + "/fifo.lcm: is a FIFO, not a regular file\n"},
      {{"plot", dir_ + "/cycles.csv", "-o", out},
       "exodaq plot: " + dir_ +
           "/cycles.csv: not an LCM log (first bytes 75 74 69 6d 65 5f 75 73)\n"},
      {{"replay", dir_ + "/cycles.csv", "-c", g_rec->config, "-o", out},
       "exodaq replay: " + dir_ +
           "/cycles.csv: not an LCM log (first bytes 75 74 69 6d 65 5f 75 "
           "73) nor a candump log (line 1, 'utime_us,seq', does not start with a '(timestamp)')\n"},
      {{"replay", dir_ + "/cycles.csv", "-c", g_rec->config, "--format", "lcm", "-o", out},
       "exodaq replay: " + dir_ +
           "/cycles.csv: not an LCM log (first bytes 75 74 69 6d 65 5f 75 73)\n"},
      {{"replay", dir_ + "/empty.lcm", "-c", g_rec->config, "-o", out},
       "exodaq replay: " + dir_ +
           "/empty.lcm: empty file, not a recording (an LCM log or a "
           "candump log)\n"},
      {{"replay", dir_ + "/fifo.lcm", "-c", g_rec->config, "-o", out},
       "exodaq replay: " + dir_ + "/fifo.lcm: is a FIFO, not a regular file\n"},
  };
  for (const Case& c : cases) {
    std::vector<std::string> argv{EXODAQ_TOOL};
    argv.insert(argv.end(), c.args.begin(), c.args.end());
    const auto r = test::run(argv, std::chrono::seconds(20));
    EXPECT_EQ(r.exit_code, 2) << c.args[0] << " " << c.args[1];
    EXPECT_EQ(r.err, c.err);
    EXPECT_FALSE(fs::exists(out)) << c.args[0] << " " << c.args[1];
  }
  // A plot whose figures cannot be made creates no folder either.
  const auto r = test::run({EXODAQ_TOOL, "plot", g_rec->log, "-o", out, "--python", "/bin/false"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("the figures could not be made"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(ToolFiles, ConfigAndModelInputsAreRegularFilesWithinTheLimit) {
  ASSERT_EQ(::mkfifo((dir_ + "/fifo.yaml").c_str(), 0600), 0);
  // The reproduction: a FIFO as config blocked --check-config forever.
  auto r =
      test::run({EXODAQD, "-c", dir_ + "/fifo.yaml", "--check-config"}, std::chrono::seconds(20));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "exodaqd: " + dir_ + "/fifo.yaml: is a FIFO, not a regular file\n");
  // /dev/zero read until std::bad_alloc.
  r = test::run({EXODAQD, "-c", "/dev/zero", "--check-config"}, std::chrono::seconds(20));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "exodaqd: /dev/zero: is a character device, not a regular file\n");
  r = test::run({EXODAQ_TOOL, "fk", "--model", "/dev/zero", "--joints-deg", "0,0,0,0,0,0"},
                std::chrono::seconds(20));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "exodaq fk: /dev/zero: is a character device, not a regular file\n");
  // A directory said "empty document".
  r = test::run({EXODAQD, "-c", dir_, "--check-config"});
  EXPECT_EQ(r.err, "exodaqd: " + dir_ + ": is a directory, not a regular file\n");
  // A missing file named by the config: the config's file:line, the path as
  // written and as resolved (it was: the path only, relative to a folder
  // nobody named).
  fs::create_directories(dir_ + "/etc");
  std::string cfg = read_text(g_rec->config);
  const std::size_t m = cfg.find("\nmodel: ");
  cfg.replace(m, cfg.find('\n', m + 1) - m, "\nmodel: models/nope.yaml");
  write_text(dir_ + "/etc/exodaqd.yaml", cfg);
  int line = 1;
  for (std::size_t i = 0; i <= m; ++i) line += cfg[i] == '\n';
  r = test::run({EXODAQD, "-c", dir_ + "/etc/exodaqd.yaml", "--check-config"});
  EXPECT_EQ(r.err, "exodaqd: " + dir_ + "/etc/exodaqd.yaml:" + std::to_string(line) +
                       ": model file 'models/nope.yaml', relative to the config's folder: " + dir_ +
                       "/etc/models/nope.yaml: cannot open: No such file or directory\n");
  // Over the documented limit, refused before reading.
  write_text(dir_ + "/big.yaml", "rig: x\n");
  ASSERT_EQ(::truncate((dir_ + "/big.yaml").c_str(), (4 << 20) + 1), 0);
  r = test::run({EXODAQD, "-c", dir_ + "/big.yaml", "--check-config"});
  EXPECT_EQ(r.err, "exodaqd: " + dir_ +
                       "/big.yaml: is 4194305 bytes, more than the 4194304-byte limit for this "
                       "input\n");
}

// Issue 16 "small items": the simulated rig (clock.require_sync: ignore) on a
// machine without NTP showed "clock NOT SYNCHRONISED, est error 16000000.0 us".
TEST(ToolStatus, AnIgnoredClockIsNotShoutedAndNoEstimateIsUnknown) {
  const std::string dir = test::make_temp_dir("status-clock");
  const std::string config = test::write_sim_config(dir, test::unique_prefix("clk"));
  test::Process daemon({EXODAQD, "-c", config, "--duration", "20"}, dir + "/d.out", dir + "/d.err");
  const auto r = test::run({EXODAQ_TOOL, "status", "-c", config, "--timeout", "10"});
  daemon.signal(SIGINT);
  daemon.wait(std::chrono::seconds(10));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::size_t at = r.out.find("\nclock    ");
  ASSERT_NE(at, std::string::npos) << r.out;
  const std::string clock = r.out.substr(at + 1, r.out.find('\n', at + 1) - at - 1);
  // Synchronised on a machine with NTP; otherwise said to be ignored.
  EXPECT_TRUE(clock.rfind("clock    synchronised", 0) == 0 ||
              clock.rfind("clock    not synchronised (ignored: clock.require_sync: ignore)", 0) ==
                  0)
      << clock;
  EXPECT_EQ(clock.find("16000000"), std::string::npos) << clock;
}

}  // namespace
}  // namespace exodaq
