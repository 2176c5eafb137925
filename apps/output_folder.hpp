#pragma once

// A command's output folder, written as one piece. The outputs go into a
// hidden staging folder beside `--out`; `commit` swaps it into place in one
// rename, so that `--out` always holds one whole output (the earlier one or
// the new one), never a mix, even when the process is killed while writing.
// The staging folder is made before any work, so an output place that cannot
// be written fails at once, not after minutes of computing.

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace dcl::apps {

class OutputFolder {
 public:
  /// Checks `out` and makes the staging folder beside it. Throws core::Error
  /// when `out` is a file, cannot be written, or holds files that no dcl-slam
  /// command wrote (unless `force`: then they are replaced). The files named in
  /// `carried` are another process's, written into `out` while this one runs
  /// (the swarm's robot.log and play.log in OUT/ROBOT): they stay in the new output, linked
  /// into it, so that their writer goes on writing into them.
  OutputFolder(std::string out, bool force, std::vector<std::string> carried = {});
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
  std::vector<std::string> carried_;
  bool committed_ = false;
};

/// Adds `--force` (replace an output folder that holds other files) to `cmd`.
void addForceFlag(CLI::App& cmd, bool& force);

/// Until the process ends, SIGINT and SIGTERM end it with a line saying that
/// the output folder keeps what it held (the default ends it without a word).
/// Commands that stop cleanly on a signal (StopSignals) override this.
void sayWhatAnInterruptDoes();

}  // namespace dcl::apps
