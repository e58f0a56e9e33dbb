// A real PostgreSQL server for a test (issue 14, point 4): initdb and pg_ctl into a temporary
// directory, a free TCP port on 127.0.0.1 and the unix socket in the directory, stopped and
// removed at the end. As root (CI), initdb refuses to run: the server then runs as `nobody`,
// which owns the directory. Where the server's binaries are missing the test process exits with
// kSkip (77), which CTest reports as SKIPPED (tests/CMakeLists.txt: SKIP_RETURN_CODE).
#pragma once

#include <netinet/in.h>
#include <pwd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace fogbench::test {

inline constexpr int kSkip = 77;

class PgServer {
 public:
  PgServer() {
    bin_ = find_bin();
    if (bin_.empty()) {
      std::cerr << "SKIPPED: no PostgreSQL server binaries (initdb, pg_ctl under /usr/lib/postgresql/*/bin or "
                   "FOGBENCH_PG_BIN); install the Debian package `postgresql`\n";
      std::exit(kSkip);
    }
    char tmpl[] = "/tmp/fogbench-pg-XXXXXX";
    if (!::mkdtemp(tmpl)) throw std::runtime_error("mkdtemp failed");
    dir_ = tmpl;
    if (::geteuid() == 0) {
      const ::passwd* pw = ::getpwnam("nobody");
      if (!pw) throw std::runtime_error("running as root and no user `nobody` to run PostgreSQL as");
      if (::chown(dir_.c_str(), pw->pw_uid, pw->pw_gid) != 0) throw std::runtime_error("chown " + dir_.string());
      as_ = "runuser -u nobody -- ";
    }
    port_ = free_port();
    run(bin("initdb") + " -D " + data() + " -U postgres --auth-local=trust --auth-host=scram-sha-256 -E UTF8 "
        "--no-sync --no-instructions > " + (dir_ / "initdb.log").string() + " 2>&1",
        "initdb");
    start();
  }
  ~PgServer() {
    (void)std::system((as_ + bin("pg_ctl") + " -D " + data() + " -m immediate stop > /dev/null 2>&1").c_str());
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  PgServer(const PgServer&) = delete;
  PgServer& operator=(const PgServer&) = delete;

  void start() {
    run(bin("pg_ctl") + " -D " + data() + " -l " + (dir_ / "server.log").string() + " -w -t 60 -o \"-p " +
            std::to_string(port_) + " -k " + dir_.string() +
            " -c listen_addresses=127.0.0.1 -c fsync=off -c synchronous_commit=off -c full_page_writes=off\" start "
            "> /dev/null 2>&1",
        "pg_ctl start");
  }
  // The server killed at once (no shutdown checkpoint, clients cut off mid-statement).
  void kill_immediate() { run(bin("pg_ctl") + " -D " + data() + " -m immediate -w stop > /dev/null 2>&1", "pg_ctl stop"); }

  int port() const { return port_; }
  // The superuser over the unix socket (trust).
  std::string conninfo(const std::string& db = "postgres") const {
    return "host=" + dir_.string() + " port=" + std::to_string(port_) + " user=postgres dbname=" + db;
  }
  // Over TCP, where a password is required.
  std::string tcp_conninfo(const std::string& password) const {
    return "host=127.0.0.1 port=" + std::to_string(port_) + " user=postgres dbname=postgres password=" + password +
           " connect_timeout=10";
  }
  // psql -At -c sql, as text.
  std::string psql(const std::string& sql) const {
    const std::filesystem::path out = dir_ / "psql.out";
    const std::string cmd = bin("psql") + " -X -At -v ON_ERROR_STOP=1 \"" + conninfo() + "\" -c \"" + sql + "\" > " +
                            out.string() + " 2>&1";
    const int rc = std::system(cmd.c_str());
    std::ifstream f(out);
    std::stringstream ss;
    ss << f.rdbuf();
    std::string s = ss.str();
    while (!s.empty() && s.back() == '\n') s.pop_back();
    if (rc != 0) throw std::runtime_error("psql failed: " + s);
    return s;
  }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  static std::string find_bin() {
    // Named explicitly: that folder or nothing (FOGBENCH_PG_BIN=/nonexistent shows the skip).
    if (const char* e = std::getenv("FOGBENCH_PG_BIN"))
      return std::filesystem::exists(std::filesystem::path(e) / "initdb") ? std::string(e) : std::string();
    std::string best;
    std::error_code ec;
    for (const auto& d : std::filesystem::directory_iterator("/usr/lib/postgresql", ec)) {
      const auto b = d.path() / "bin";
      if (std::filesystem::exists(b / "initdb") && std::filesystem::exists(b / "pg_ctl") && b.string() > best)
        best = b.string();
    }
    return best;
  }
  static int free_port() {
    const int s = ::socket(AF_INET, SOCK_STREAM, 0);
    ::sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = 0;
    if (::bind(s, reinterpret_cast<::sockaddr*>(&a), sizeof a) != 0) throw std::runtime_error("bind");
    ::socklen_t len = sizeof a;
    ::getsockname(s, reinterpret_cast<::sockaddr*>(&a), &len);
    ::close(s);
    return ntohs(a.sin_port);
  }
  std::string bin(const std::string& name) const {
    // psql is the client's, found beside the server binaries or on the PATH.
    const auto p = std::filesystem::path(bin_) / name;
    return std::filesystem::exists(p) ? p.string() : name;
  }
  std::string data() const { return (dir_ / "data").string(); }
  void run(const std::string& cmd, const std::string& what) const {
    const std::string full = name_prefix(cmd);
    if (std::system(full.c_str()) != 0) {
      std::ifstream log(dir_ / (what == "initdb" ? "initdb.log" : "server.log"));
      std::stringstream ss;
      ss << log.rdbuf();
      throw std::runtime_error(what + " failed: " + ss.str());
    }
  }
  std::string name_prefix(const std::string& cmd) const { return as_ + cmd; }

  std::string bin_;
  std::filesystem::path dir_;
  std::string as_;  // "runuser -u nobody -- " as root
  int port_ = 0;
};

}  // namespace fogbench::test
