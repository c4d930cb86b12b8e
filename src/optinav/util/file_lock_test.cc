#include "optinav/util/file_lock.h"

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include "optinav/util/testing.h"

namespace optinav {
namespace {

// fcntl locks are per process: a child process must wait until the parent lets go.
TEST(FileLock, AnotherProcessWaitsForTheHolder) {
  const auto dir = testing::MakeTempDir("file_lock");
  const std::string lock_path = (dir / "x.lock").string();
  const std::string log = (dir / "order.txt").string();
  {
    FileLock held(lock_path);
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      {
        FileLock mine(lock_path);
        std::ofstream(log, std::ios::app) << "child\n";
      }
      _exit(0);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    std::ofstream(log, std::ios::app) << "parent\n";
  }  // released here: the child goes on
  int status = 0;
  while (waitpid(-1, &status, 0) < 0 && errno == EINTR) {
  }
  EXPECT_EQ(testing::ReadFile(log), "parent\nchild\n");
  EXPECT_ERROR(FileLock((dir / "no" / "such" / "dir.lock").string()), {.file = "dir.lock"},
               "cannot open lock file");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace optinav
