#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace hw::core {

// One run owns an output folder at a time, and a folder a run did not finish says so.
//
// Every command that writes a folder (a scan, a reconstruction, a report) holds an
// OutputFolder for the whole run. It keeps a run marker, <folder>/.heatwave-run, locked with
// flock() while the run lasts: a second run into the same folder fails at once instead of
// mixing its files with the first one's, and readers refuse a folder being written. The
// marker is removed by Commit() when the run has written everything; a run that fails, is
// interrupted or killed leaves it behind (the kernel drops the lock with the process), so
// the folder reads as incomplete rather than as a valid scan with missing parts.

// File name of the run marker inside an output folder.
inline constexpr const char* kRunMarkerName = ".heatwave-run";

class OutputFolder {
 public:
  // Creates `folder` (and parents) if missing and takes the run lock. `description` names
  // the run in the marker and in other runs' messages (e.g. "heatwave synth"). Throws
  // OutputError naming the folder when it cannot be created or another run holds it
  // ("another heatwave run is writing it (pid 4242, heatwave synth, started ...)").
  OutputFolder(const std::filesystem::path& folder, const std::string& description);
  // Releases the lock. Without Commit() the marker stays: the folder reads as incomplete.
  ~OutputFolder();
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;

  const std::filesystem::path& folder() const { return folder_; }

  // True when the folder holds nothing but the run marker.
  bool IsEmpty() const;
  // Removes these entries (files or whole folders, relative names) if present: what
  // --overwrite replaces. Throws OutputError naming the entry that cannot be removed.
  void Remove(const std::vector<std::string>& entries) const;
  // The run wrote everything: removes the marker and releases the lock. Throws OutputError.
  void Commit();
  // The run gives the folder up before writing anything (e.g. it refuses a non-empty
  // folder): the marker is removed if this run created it, so the folder reads as before.
  void Abandon();

 private:
  std::filesystem::path folder_;
  int fd_ = -1;
  bool committed_ = false;
  bool created_marker_ = false;  // no marker was there before this run
};

// What the run marker of `folder` says, for readers.
enum class FolderRunState {
  kComplete,      // no marker: no run is writing it and the last one finished
  kBeingWritten,  // a live run holds the marker's lock
  kIncomplete,    // a marker without a live run: the run that wrote it did not finish
};
struct FolderRun {
  FolderRunState state = FolderRunState::kComplete;
  std::string detail;  // the marker's description of its run ("pid 4242, heatwave synth, ...")
};
FolderRun ProbeFolderRun(const std::filesystem::path& folder);

}  // namespace hw::core
