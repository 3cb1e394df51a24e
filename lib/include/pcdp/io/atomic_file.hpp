// Outputs are committed as a set (docs/data_contract.md "Conventions", docs/robustness.md "Outputs").
//
// A run's products are written into a staging folder beside the output folder, on the same
// filesystem: `<parent>/.<name>.pcdp-new-<pid>`. On commit, the files of the old folder that are
// not products of this run (the user's own files, earlier products of stages not in this run)
// are hard-linked into it, and the staging folder and the output folder are swapped in one step
// (renameat2 RENAME_EXCHANGE; a plain rename when the output folder does not exist yet). The old
// set, now under the staging name, is then removed. Whoever opens the folder by its path sees the
// complete old set or the complete new set, never a mix; a run that fails or is killed at any
// instant leaves the old folder as it was (or, when it did not exist, no folder at all).
//
// Filesystems without RENAME_EXCHANGE (NFS, some FUSE): the old folder is renamed aside to
// `<parent>/.<name>.pcdp-old-<pid>` and the staging folder renamed in its place. Between the
// two renames the folder is absent (still never mixed); a kill in that instant leaves the old set
// under the aside name, and the next run into the folder renames it back before it starts.
//
// One run at a time per output: an advisory lock (flock) on `<parent>/.<name>.pcdp-lock`,
// held for the whole run; a second run refuses at once (OutputError). The kernel drops the lock
// when its holder dies, so a killed run never blocks the next one. Holding the lock, a run removes
// every `.<name>.pcdp-*` leftover of killed runs before it starts.
#pragma once

#include <memory>
#include <string>
#include <vector>

namespace pcdp::io {

/// An exclusive advisory lock on `<parent>/.<name>.pcdp-lock` beside the output `target` (a folder
/// or a file), held while the object lives; the lock file is removed when it is released.
/// Throws OutputError at once, naming the holder's pid, if another process holds it.
class OutputLock {
 public:
  explicit OutputLock(const std::string& target);
  ~OutputLock();
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
  int slot_ = -1;  // in the signal cleanup table
};

/// Refuses (ConfigError naming `key`) an output path that is empty, contains a control character,
/// or names no folder entry that can be replaced ("/", ".", "..").
void check_output_path(const std::string& key, const std::string& path);

/// Refuses (ConfigError, exit 2) an input inside the output folder `dir` (at any depth) under one
/// of `names`, the folder entries a command writes or replaces: its commit would replace it. For
/// checks before a StagedOutputs exists (a shard plan); StagedOutputs::protect_inputs does the same.
void check_inputs_not_replaced(const std::string& dir, const std::vector<std::string>& inputs,
                               const std::vector<std::string>& names);

/// The products of a run, committed as a set into an output folder (see the top of this file).
class StagedOutputs final {
 public:
  /// Takes the folder's lock, removes leftovers of killed runs, creates the staging folder
  /// (and the output folder's missing parents, removed again if the run fails). Throws
  /// OutputError if `dir` exists and is not a folder, or cannot be written beside.
  explicit StagedOutputs(std::string dir);
  ~StagedOutputs();  // removes the staging folder (and the parents it created) unless committed
  StagedOutputs(const StagedOutputs&) = delete;
  StagedOutputs& operator=(const StagedOutputs&) = delete;

  /// Refuses (OutputError) product names that the existing folder holds as a folder: the
  /// commit would have to replace it. Called before the work starts.
  void check_replaceable(const std::vector<std::string>& filenames) const;
  /// `<staging>/<filename>`; a name given twice is a bug (std::logic_error).
  std::string staged_path(const std::string& filename);
  /// Names this command owns in the folder (every product it may write, whether or not this run
  /// writes it): the old folder's entries of these names are not carried over to the new set, so a
  /// run that no longer writes map.ot (say) leaves no earlier map.ot beside its new map.bt.
  void owns(std::vector<std::string> names);
  /// The command's input files: one inside the output folder (at any depth) under the name of a
  /// product (staged or owned; a product folder such as truth/ holds its inputs too) would be
  /// replaced by the commit, so that is refused (ConfigError, exit 2, naming the input and the
  /// folder) here, in owns() and in staged_path(), before the work, and again at the commit.
  void protect_inputs(const std::vector<std::string>& inputs);
  std::string final_path(const std::string& filename) const;
  /// The final paths of everything staged so far.
  std::vector<std::string> final_paths() const;
  /// The names of everything staged so far, in the order staged.
  const std::vector<std::string>& names() const { return names_; }
  /// Swaps the new set into place. Throws OutputError (the old set intact) if it cannot.
  /// Warnings (the old set could not be removed: the next run removes it) go to stderr.
  void commit();
  const std::string& dir() const { return dir_; }
  const std::string& staging_dir() const { return staging_; }

 private:
  std::string dir_;      // as given
  std::string target_;   // absolute, symlinks of the folder itself resolved
  std::string staging_;
  std::vector<std::string> created_parents_;  // innermost last
  std::unique_ptr<OutputLock> lock_;
  std::vector<std::string> names_;
  std::vector<std::string> owned_;
  std::vector<std::pair<std::string, std::string>> inputs_;  // (as given, folder entry) of inputs inside the folder
  void check_inputs(const std::string& name) const;
  void commit_steps();
  int slot_ = -1;  // in the signal cleanup table
  bool committed_ = false;
};

/// Single files in any folders committed together (merge: the .tif and the PNG; clean-cloud:
/// the cleaned and the removed points). Each is written to `<folder>/.<name>.pcdp-tmp-<pid>` and
/// locked (OutputLock) when added, so an unwritable folder fails before the work. commit()
/// swaps them in one after the other (RENAME_EXCHANGE, or a backup hard link); when a step fails
/// the files already swapped are swapped back, so a failure leaves every old file. A SIGINT or
/// SIGTERM during the commit waits for its end; only a SIGKILL or a power loss in the
/// microseconds between two renames can leave some files new and some old.
class StagedFiles {
 public:
  StagedFiles() = default;
  ~StagedFiles();  // removes the temporaries unless committed
  StagedFiles(const StagedFiles&) = delete;
  StagedFiles& operator=(const StagedFiles&) = delete;
  /// The temporary path for `final_path` (created empty now). `key` names the option in errors.
  std::string add(const std::string& key, const std::string& final_path);
  void commit();

 private:
  struct Item {
    std::string tmp, fin;
    std::unique_ptr<OutputLock> lock;
    int slot = -1;  // in the signal cleanup table
  };
  std::vector<Item> items_;
  bool committed_ = false;
};

/// A scratch folder for a command's own intermediate files (`pcd_pipeline bench`'s simulated
/// passes and runs): created empty (a leftover of the same path is removed first) and removed
/// when this object is destroyed, and, once install_signal_cleanup() is in place, by SIGINT,
/// SIGTERM or SIGHUP before the process exits. Throws OutputError when it cannot be created.
class ScratchFolder {
 public:
  explicit ScratchFolder(std::string path);
  ~ScratchFolder();
  ScratchFolder(const ScratchFolder&) = delete;
  ScratchFolder& operator=(const ScratchFolder&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int slot_ = -1;  // in the signal cleanup table
};

/// Writes `content` to `path` atomically (temporary file in the same folder, then rename).
/// Throws OutputError naming the path and the reason.
void write_file_atomic(const std::string& path, const std::string& content);

/// Makes SIGINT and SIGTERM remove the temporaries of the commits in progress (staging folders,
/// temporary files) and exit with 128 + the signal. A signal that arrives during a commit's
/// swap waits for the swap's end. Called once by the CLI.
void install_signal_cleanup();

namespace detail {
/// Test hook: called before each filesystem step of a commit (1-based, in order) with a short
/// description; a non-zero return makes the step fail with that errno (a hook may also kill the
/// process). Unset, the environment variable PCDP_TEST_COMMIT_FAULT="fail:N" or "kill:N" (test
/// use only) fails step N with EIO or sends SIGKILL before it.
using CommitStepHook = int (*)(int step, const char* what);
void set_commit_step_hook(CommitStepHook hook);
}  // namespace detail

}  // namespace pcdp::io
