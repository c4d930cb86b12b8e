// An exclusive advisory lock on a file (POSIX fcntl record lock), held for the object's life:
// independent processes (Slurm tasks on one node or on a shared NFS/Lustre folder, where fcntl
// locks are served by the file system) take turns at one job, e.g. rendering a sequence that
// several tasks need.
#pragma once

#include <string>

namespace optinav {

class FileLock {
 public:
  // Creates `path` when missing and waits until the lock is ours. Throws Error naming the file
  // when it cannot be created or locked.
  explicit FileLock(const std::string& path);
  ~FileLock();
  FileLock(const FileLock&) = delete;
  FileLock& operator=(const FileLock&) = delete;

 private:
  int fd_ = -1;
};

}  // namespace optinav
