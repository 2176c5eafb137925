#pragma once

// A command's output folder, written as one piece. The outputs go into a
// hidden staging folder beside `--out`; `commit` swaps it into place in one
// rename, so that `--out` always holds one whole output (the earlier one or
// the new one), never a mix, even when the process is killed while writing.
// The staging folder is made before any work, so an output place that cannot
// be written fails at once, not after minutes of computing.

#include <string>

namespace CLI {
class App;
}

namespace dcl::apps {

class OutputFolder {
 public:
  /// Checks `out` and makes the staging folder beside it. Throws core::Error
  /// when `out` is a file, cannot be written, or holds files that no dcl-slam
  /// command wrote (unless `force`: then they are replaced).
  OutputFolder(std::string out, bool force);
  /// Removes the staging folder unless it was committed.
  ~OutputFolder();
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;

  /// Where to write the outputs until `commit`.
  [[nodiscard]] const std::string& path() const { return staging_; }
  /// The folder the user named.
  [[nodiscard]] const std::string& out() const { return out_; }

  /// Throws core::Error when `input` (named `what` in the message) lies in
  /// `out`, which the outputs replace.
  void requireOutside(const std::string& input, const std::string& what) const;

  /// Puts the outputs in place of `out` (and of what it held) in one rename.
  void commit();

 private:
  std::string out_;
  std::string staging_;
  bool committed_ = false;
};

/// Creates `folder` and checks that a file can be written in it; throws
/// core::Error naming the folder and the reason. For commands that write into
/// a folder shared with others (`robot` writes OUT/ROBOT), checked before the work.
void requireWritableFolder(const std::string& folder);

/// Adds `--force` (replace an output folder that holds other files) to `cmd`.
void addForceFlag(CLI::App& cmd, bool& force);

/// Until the process ends, SIGINT and SIGTERM end it with a line saying that
/// the output folder keeps what it held (the default ends it without a word).
/// Commands that stop cleanly on a signal (StopSignals) override this.
void sayWhatAnInterruptDoes();

}  // namespace dcl::apps
