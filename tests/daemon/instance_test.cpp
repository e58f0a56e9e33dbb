// One daemon per store and per socket path (instance.hpp), without a daemon: the store's lock,
// the socket file's take-over and removal, and the modes of what is created under any umask.
#include <catch2/catch.hpp>

#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>

#include "fogbench/daemon/instance.hpp"

using namespace fogbench::daemon;
namespace fs = std::filesystem;

namespace {

struct TempDir {
  fs::path dir;
  TempDir() {
    char tmpl[] = "/tmp/fogbench-instance-XXXXXX";
    dir = ::mkdtemp(tmpl);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

// Sets the umask for one scope (the tests' own process: no other thread creates files).
struct Umask {
  ::mode_t old;
  explicit Umask(::mode_t m) : old(::umask(m)) {}
  ~Umask() { ::umask(old); }
};

::mode_t mode_of(const fs::path& p) {
  struct stat st{};
  REQUIRE(::lstat(p.c_str(), &st) == 0);
  return st.st_mode & 07777;
}

// A unix socket bound at `path`, listening or not.
int bind_socket(const fs::path& path, bool listen) {
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  std::strncpy(a.sun_path, path.c_str(), sizeof a.sun_path - 1);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  REQUIRE(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0);
  if (listen) REQUIRE(::listen(fd, 4) == 0);
  return fd;
}

}  // namespace

TEST_CASE("instance: a second lock on a store is refused, naming the holder's pid") {
  TempDir t;
  const fs::path store = t.dir / "fogbench.db";
  auto got = StoreLock::acquire(store);
  REQUIRE(got.has_value());
  std::optional<StoreLock> first(std::move(*got));
  CHECK(first->path() == t.dir / "fogbench.db.lock");
  // flock belongs to the open file description, so a second open in this process conflicts
  // exactly as another process's would.
  auto second = StoreLock::acquire(store);
  REQUIRE_FALSE(second.has_value());
  CHECK(second.error().held_by_other);
  CHECK_THAT(second.error().message, Catch::Contains("pid " + std::to_string(::getpid())));
  // The pid is in the file for people too.
  std::ifstream in(first->path());
  long pid = 0;
  in >> pid;
  CHECK(pid == ::getpid());
  // Released with its holder: the next daemon takes it.
  first.reset();
  CHECK(StoreLock::acquire(store).has_value());
}

TEST_CASE("instance: the lock file and the socket's folders have their modes under any umask") {
  for (::mode_t mask : {::mode_t{0}, ::mode_t{077}, ::mode_t{022}}) {
    INFO("umask " << std::oct << mask);
    TempDir t;
    Umask u(mask);
    auto lock = StoreLock::acquire(t.dir / "s.db");
    REQUIRE(lock.has_value());
    CHECK(mode_of(lock->path()) == kStoreFileMode);  // 0640
    REQUIRE(make_dirs(t.dir / "run" / "fogbench").has_value());
    CHECK(mode_of(t.dir / "run") == 0750);
    CHECK(mode_of(t.dir / "run" / "fogbench") == 0750);
  }
}

TEST_CASE("instance: a socket path another process answers on is not taken over") {
  TempDir t;
  const fs::path path = t.dir / "d.sock";
  const int live = bind_socket(path, true);
  auto r = clear_stale_socket(path);
  REQUIRE_FALSE(r.has_value());
  CHECK(r.error().held_by_other);
  CHECK(fs::exists(path));
  ::close(live);
  // Nobody listens now (a crashed daemon's file): stale, removed.
  REQUIRE(clear_stale_socket(path).has_value());
  CHECK_FALSE(fs::exists(path));
  CHECK(clear_stale_socket(path).has_value());  // nothing there: nothing to do
  // A file that is not a socket is never deleted.
  std::ofstream(t.dir / "f.sock") << "data";
  auto f = clear_stale_socket(t.dir / "f.sock");
  REQUIRE_FALSE(f.has_value());
  CHECK_FALSE(f.error().held_by_other);
  CHECK(fs::exists(t.dir / "f.sock"));
}

TEST_CASE("instance: on exit only the socket file this process bound is removed") {
  TempDir t;
  const fs::path path = t.dir / "d.sock";
  const int mine = bind_socket(path, true);
  const SocketFileId id = socket_file_id(path);
  REQUIRE(id.valid);
  // Another daemon took the path over (removed ours and bound its own): its file stays.
  REQUIRE(::unlink(path.c_str()) == 0);
  const int theirs = bind_socket(path, true);
  CHECK_FALSE(remove_if_ours(path, id));
  CHECK(fs::exists(path));
  ::close(theirs);
  // Still ours: removed.
  REQUIRE(::unlink(path.c_str()) == 0);
  const int again = bind_socket(path, true);
  CHECK(remove_if_ours(path, socket_file_id(path)));
  CHECK_FALSE(fs::exists(path));
  ::close(again);
  ::close(mine);
}
