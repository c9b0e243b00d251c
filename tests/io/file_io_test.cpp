// file_io.hpp: reading never blocks and never runs away, writing replaces atomically and
// only what is ours, one writer at a time.
#include "omnipose/file_io.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <string>

#include "test_files.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

class FileIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            ("omnipose_file_io_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    fs::create_directories(root_);
  }
  void TearDown() override { fs::remove_all(root_); }

  fs::path write(const std::string& name, const std::string& text) {
    const fs::path p = root_ / name;
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }
  /// The names in root_ (to see that no temporary file is left behind).
  std::vector<std::string> names() const {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(root_)) out.push_back(e.path().filename().string());
    std::sort(out.begin(), out.end());
    return out;
  }
  fs::path root_;
};

constexpr FileKind kWisdom{"an FFTW wisdom file", looksLikeFftwWisdom};
constexpr const char* kWisdomText = "(fftw-3.3.10 fftwf_wisdom #x1d2a1c8e #x0 #x0 #x0\n)\n";

std::string messageOf(const Error& e) { return std::string(e.message()); }

TEST_F(FileIoTest, ReadsARegularFileWhole) {
  const fs::path p = write("a.txt", "one\ntwo\n");
  const Expected<std::string> text = readTextFile(p);
  ASSERT_TRUE(text) << text.error().c_str();
  EXPECT_EQ(*text, "one\ntwo\n");
  EXPECT_EQ(readTextFileOrThrow(p), "one\ntwo\n");
}

TEST_F(FileIoTest, FifosDevicesDirectoriesAndSocketsAreRefusedByNameAtOnce) {
  const fs::path fifo = root_ / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const fs::path socket_path = root_ / "sock";
  const int s = ::socket(AF_UNIX, SOCK_STREAM, 0);
  ASSERT_GE(s, 0);
  sockaddr_un address{};
  address.sun_family = AF_UNIX;
  std::snprintf(address.sun_path, sizeof(address.sun_path), "%s", socket_path.c_str());
  ASSERT_EQ(::bind(s, reinterpret_cast<sockaddr*>(&address), sizeof(address)), 0);
  struct Case {
    fs::path path;
    std::string says;
  };
  const std::vector<Case> cases = {{fifo, "not a regular file (a FIFO)"},
                                   {"/dev/zero", "not a regular file (a character device)"},
                                   {root_, "not a regular file (a directory)"},
                                   {socket_path, "not a regular file"},
                                   {root_ / "missing", "no such file"}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.path);
    const auto start = Clock::now();
    const Expected<std::string> text = readTextFile(c.path);
    EXPECT_LT(Clock::now() - start, std::chrono::seconds(1)) << "a FIFO without a writer must not block";
    ASSERT_FALSE(text);
    EXPECT_EQ(messageOf(text.error()).find(c.path.string() + ": "), 0u) << text.error().c_str();
    EXPECT_THAT(messageOf(text.error()), HasSubstr(c.says)) << text.error().c_str();
  }
  ::close(s);
}

TEST_F(FileIoTest, AFileLargerThanTheBoundIsRefusedUnread) {
  const fs::path p = write("big.txt", std::string(5000, 'x'));
  const Expected<std::string> text = readTextFile(p, 4096);
  ASSERT_FALSE(text);
  EXPECT_THAT(messageOf(text.error()), HasSubstr("5000 bytes, more than the 4096 allowed"))
      << text.error().c_str();
  EXPECT_EQ(kMaxTextFileBytes, std::uintmax_t{64} << 20);
}

TEST_F(FileIoTest, RecognisesWisdomAndLcmLogsByTheirFirstBytes) {
  EXPECT_TRUE(looksLikeFftwWisdom(kWisdomText));
  EXPECT_TRUE(looksLikeFftwWisdom("(fftw-3.3.8 fftw_wisdom #x0\n)"));
  EXPECT_FALSE(looksLikeFftwWisdom("omni:\n  model: linear\n"));
  EXPECT_FALSE(looksLikeFftwWisdom("(fftw-3.3.10"));
  EXPECT_TRUE(looksLikeLcmLog(std::string("\xED\xA1\xDA\x01rest", 8)));
  EXPECT_FALSE(looksLikeLcmLog("\xED\xA1"));
}

TEST_F(FileIoTest, AtomicWriteCreatesAndReplacesItsOwnKindOnly) {
  const fs::path target = root_ / "wisdom.txt";
  ASSERT_TRUE(writeFileAtomically(target, kWisdomText, kWisdom));
  EXPECT_EQ(testing::readText(target), kWisdomText);
  ASSERT_TRUE(writeFileAtomically(target, std::string(kWisdomText) + "\n", kWisdom));
  EXPECT_EQ(testing::readText(target), std::string(kWisdomText) + "\n");
  EXPECT_EQ(names(), std::vector<std::string>{"wisdom.txt"}) << "no temporary file left behind";

  const fs::path empty = write("empty.txt", "");
  EXPECT_TRUE(writeFileAtomically(empty, kWisdomText, kWisdom)) << "an empty file is replaceable";

  const std::string calibration = "omni:\n  model: linear\n";
  const fs::path foreign = write("calibration.yaml", calibration);
  const Expected<void> refused = writeFileAtomically(foreign, kWisdomText, kWisdom);
  ASSERT_FALSE(refused);
  EXPECT_THAT(messageOf(refused.error()),
              HasSubstr("calibration.yaml: exists and is not an FFTW wisdom file"))
      << refused.error().c_str();
  EXPECT_EQ(testing::readText(foreign), calibration) << "the foreign file is untouched";
}

TEST_F(FileIoTest, AtomicWriteNeverGoesThroughASymbolicLinkOrIntoAFifo) {
  const fs::path own = write("real_wisdom.txt", kWisdomText);
  const fs::path link = root_ / "link.txt";
  fs::create_symlink(own, link);
  const Expected<void> via_link = writeFileAtomically(link, "(fftw-3.3.10 fftwf_wisdom new\n)", kWisdom);
  ASSERT_FALSE(via_link);
  EXPECT_THAT(messageOf(via_link.error()), HasSubstr("is a symbolic link"))
      << via_link.error().c_str();
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(testing::readText(own), kWisdomText);

  const fs::path fifo = root_ / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto start = Clock::now();
  const Expected<void> into_fifo = writeFileAtomically(fifo, kWisdomText, kWisdom);
  EXPECT_LT(Clock::now() - start, std::chrono::seconds(1));
  ASSERT_FALSE(into_fifo);
  EXPECT_THAT(messageOf(into_fifo.error()), HasSubstr("not a regular file (a FIFO)"))
      << into_fifo.error().c_str();
  EXPECT_TRUE(fs::is_fifo(fifo));

  const Expected<void> no_dir = writeFileAtomically(root_ / "none/w.txt", kWisdomText, kWisdom);
  ASSERT_FALSE(no_dir);
  EXPECT_THAT(messageOf(no_dir.error()), HasSubstr("does not exist")) << no_dir.error().c_str();
}

TEST_F(FileIoTest, CreateReplacingGivesAFreshFileInsteadOfTruncatingTheOld) {
  constexpr FileKind kLog{"an LCM log", looksLikeLcmLog};
  const fs::path log = write("run.lcm", std::string("\xED\xA1\xDA\x01old", 7));
  // A reader that still has the old log open keeps reading the old content.
  std::ifstream old_reader(log, std::ios::binary);
  const Expected<int> fd = createReplacing(log, kLog);
  ASSERT_TRUE(fd) << fd.error().c_str();
  ASSERT_EQ(::write(*fd, "new", 3), 3);
  ::close(*fd);
  EXPECT_EQ(testing::readText(log), "new");
  std::string old_text((std::istreambuf_iterator<char>(old_reader)), {});
  EXPECT_EQ(old_text.substr(4), "old");

  const fs::path other = write("notes.txt", "keep me");
  ASSERT_FALSE(createReplacing(other, kLog));
  EXPECT_EQ(testing::readText(other), "keep me");
}

TEST_F(FileIoTest, ALockFileRefusesASecondHolderWithThePidAndIsFreedWhenTheHolderDies) {
  const fs::path path = root_ / "run.lcm.lock";
  {
    Expected<FileLock> first = FileLock::acquire(path);
    ASSERT_TRUE(first) << first.error().c_str();
    EXPECT_TRUE(first->held());
    const Expected<FileLock> second = FileLock::acquire(path);
    ASSERT_FALSE(second);
    EXPECT_EQ(second.error().code(), ErrorCode::kBusy);
    EXPECT_THAT(messageOf(second.error()),
                HasSubstr("held by process " + std::to_string(::getpid())))
        << second.error().c_str();
  }
  EXPECT_TRUE(FileLock::acquire(path)) << "released by the destructor";

  // A holder killed with SIGKILL frees it too (the kernel drops the flock).
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    Expected<FileLock> held = FileLock::acquire(path);
    const char c = held ? 'y' : 'n';
    (void)!::write(ready[1], &c, 1);
    ::pause();
    ::_exit(0);
  }
  char c = 0;
  ASSERT_EQ(::read(ready[0], &c, 1), 1);
  ASSERT_EQ(c, 'y');
  const Expected<FileLock> while_alive = FileLock::acquire(path);
  ASSERT_FALSE(while_alive);
  EXPECT_THAT(messageOf(while_alive.error()), HasSubstr("held by process " + std::to_string(child)))
      << while_alive.error().c_str();
  ::kill(child, SIGKILL);
  ::waitpid(child, nullptr, 0);
  EXPECT_TRUE(FileLock::acquire(path)) << "free after the holder was killed";
  ::close(ready[0]);
  ::close(ready[1]);
}

TEST_F(FileIoTest, ALockOnAFileItselfNamesTheHolderFromProcLocks) {
  const fs::path device = write("video0", "");
  Expected<FileLock> first = FileLock::acquireOn(device);
  ASSERT_TRUE(first) << first.error().c_str();
  const Expected<FileLock> second = FileLock::acquireOn(device);
  ASSERT_FALSE(second);
  EXPECT_EQ(second.error().code(), ErrorCode::kBusy);
  EXPECT_THAT(messageOf(second.error()), HasSubstr("held by process " + std::to_string(::getpid())))
      << second.error().c_str();
  EXPECT_EQ(testing::readText(device), "") << "nothing written into the locked file";
  first = FileLock{};
  EXPECT_TRUE(FileLock::acquireOn(device));
  EXPECT_EQ(FileLock::acquireOn(root_ / "missing").error().code(), ErrorCode::kNotFound);
}

TEST_F(FileIoTest, ALockFileThatIsASymbolicLinkIsRefused) {
  const fs::path target = write("elsewhere", "precious");
  fs::create_symlink(target, root_ / "x.lock");
  const Expected<FileLock> lock = FileLock::acquire(root_ / "x.lock");
  ASSERT_FALSE(lock);
  EXPECT_THAT(messageOf(lock.error()), HasSubstr("symbolic link")) << lock.error().c_str();
  EXPECT_EQ(testing::readText(target), "precious");
}

}  // namespace
}  // namespace omnipose
