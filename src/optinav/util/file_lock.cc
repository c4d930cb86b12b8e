#include "optinav/util/file_lock.h"

#include <cerrno>
#include <cstring>

#include <fcntl.h>
#include <unistd.h>

#include "optinav/util/error.h"

namespace optinav {

FileLock::FileLock(const std::string& path) {
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0)
    throw Error(std::string("cannot open lock file: ") + std::strerror(errno), {.file = path});
  struct flock lock = {};
  lock.l_type = F_WRLCK;
  lock.l_whence = SEEK_SET;
  int rc;
  while ((rc = ::fcntl(fd_, F_SETLKW, &lock)) < 0 && errno == EINTR) {
  }
  if (rc < 0) {
    const int err = errno;
    ::close(fd_);
    throw Error(std::string("cannot lock: ") + std::strerror(err), {.file = path});
  }
}

FileLock::~FileLock() { ::close(fd_); }  // closing releases the lock

}  // namespace optinav
