#pragma once
// Reading and writing the files a user names, the same way in every tool
// (docs/robustness.md "Files"):
//  - inputs: opened without blocking (a FIFO does not hang the open), refused
//    unless a regular file within a documented size limit, before anything is
//    read; text checked for NUL bytes and invalid UTF-8, with the line;
//  - outputs (OutputFile): written to a temporary file beside the target,
//    fsync'ed, renamed over the target only when complete; a symlink (the
//    last name or a folder on the way) is followed (its target replaced, the
//    link kept) only when it is the caller's, or root's in a folder of the
//    caller's or root's (never in a sticky world-writable folder not root's):
//    fs.protected_symlinks in user space, whatever the sysctl says; the
//    folder is held open from the checks to the rename; anything that is not
//    a regular file is refused, and so are a file the user may not write and
//    an output that is one of the inputs;
//    every error names the file and errno's reason, and leaves no partial
//    file. "-" is standard output where the caller allows it (text outputs).
// Errors are FileError "<file>: <what>". Off the loop thread only.
#include <sys/types.h>

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace exodaq::files {

class FileError : public std::runtime_error {
 public:
  FileError(const std::string& file, const std::string& what);
  const std::string& file() const noexcept { return file_; }
  const std::string& reason() const noexcept { return reason_; }

 private:
  std::string file_;
  std::string reason_;
};

// Size limits of inputs read whole into memory (docs/robustness.md).
inline constexpr std::int64_t kMaxYamlBytes = 4LL << 20;  // config, model, calibration, ...
inline constexpr std::int64_t kMaxCsvBytes = 1LL << 30;   // encoder and marker CSVs

// errno's text ("No space left on device").
std::string errno_text(int err);
// "a FIFO", "a directory", "a character device", ... for a st_mode.
std::string file_kind(mode_t mode);

// What an input check found: the open descriptor's size and identity.
struct InputInfo {
  std::int64_t size = 0;
  dev_t dev = 0;
  ino_t ino = 0;
};

// Opens `path` read-only and without blocking, refuses anything that is not
// a regular file or is larger than `max_bytes` (< 0: no limit), and returns
// the open descriptor (the caller closes it). Throws FileError.
int open_input(const std::string& path, std::int64_t max_bytes, InputInfo* info = nullptr);
// The same checks, closing the file again (for readers that open it themselves).
InputInfo check_input(const std::string& path, std::int64_t max_bytes);
// The whole file, after the checks above.
std::string read_input(const std::string& path, std::int64_t max_bytes);

// The first NUL byte or invalid UTF-8 sequence in `text`: its 1-based line and
// column and what it is; nullopt when the text is clean.
struct TextProblem {
  int line = 0;
  int column = 0;
  std::string what;  // "invalid UTF-8 (byte 0xff)", without the place
  std::string what_and_column() const { return what + " at column " + std::to_string(column); }
};
std::optional<TextProblem> find_text_problem(std::string_view text);

struct OutputOptions {
  bool allow_stdout = false;        // "-" writes to standard output
  std::vector<std::string> inputs;  // files this output must not replace
};

// Throws FileError when `path` could not be written as an output with these
// options (not a regular file, one of the inputs, directory missing). Creates
// nothing: tools call it before reading their inputs.
void check_output(const std::string& path, const OutputOptions& options = {});

class OutputFile {
 public:
  // Checks the target (as check_output) and creates the temporary file.
  explicit OutputFile(const std::string& path, const OutputOptions& options = {});
  ~OutputFile();  // without commit(): the temporary file is removed
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  // Buffered; throws FileError with errno's reason (the temporary file is
  // removed then).
  void write(std::string_view bytes);
  void write(const void* data, std::size_t size) {
    write(std::string_view(static_cast<const char*>(data), size));
  }
  // Hands the buffer to the kernel (standard output: the reader sees it now).
  void flush();
  // Flushes, fsyncs and renames over the target (standard output: flushes).
  void commit();
  // Removes the temporary file; the target is left as it was.
  void discard() noexcept;

  bool is_stdout() const noexcept { return stdout_; }
  const std::string& path() const noexcept { return path_; }  // as given
  // Where the bytes go: the path after following symlinks.
  const std::string& target() const noexcept { return target_; }
  std::int64_t bytes() const noexcept { return bytes_; }

 private:
  [[noreturn]] void fail(const std::string& what, int err);
  void write_all(const char* p, std::size_t n);

  std::string path_;
  std::string target_;
  std::string temp_;       // the temporary file as text, for messages
  std::string temp_name_;  // its name in dir_fd_
  std::string name_;       // the target's name in dir_fd_
  std::string buffer_;
  int dir_fd_ = -1;  // the target's folder, held open from the checks to the rename
  int fd_ = -1;
  bool stdout_ = false;
  bool done_ = false;
  std::int64_t bytes_ = 0;
};

// Writes `bytes` to `path` through an OutputFile.
void write_output(const std::string& path, std::string_view bytes,
                  const OutputOptions& options = {});

// Levenshtein distance (insertions, deletions, substitutions).
int edit_distance(std::string_view a, std::string_view b);
// How many edits still make a likely misspelling of `word`: 1/3 of its
// letters, at least 1, at most 3.
int typo_allowance(std::string_view word);

// The closest of `candidates` to `word` by edit distance, when close enough to
// be a likely misspelling (within typo_allowance, or one the start of the
// other); "" otherwise.
std::string closest_match(std::string_view word, const std::vector<std::string>& candidates);

}  // namespace exodaq::files
