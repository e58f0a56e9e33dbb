// plant::Connection over libpq: connecting, statements with parameters, COPY FROM STDIN.
#include "pg.hpp"

#include <memory>

namespace fogbench::plant {

std::string_view to_string(PlantErrc code) {
  switch (code) {
    case PlantErrc::connect_failed: return "connect_failed";
    case PlantErrc::connection_lost: return "connection_lost";
    case PlantErrc::schema_too_new: return "schema_too_new";
    case PlantErrc::schema_missing: return "schema_missing";
    case PlantErrc::migration_failed: return "migration_failed";
    case PlantErrc::invalid_argument: return "invalid_argument";
    case PlantErrc::bench_store: return "bench_store";
    case PlantErrc::sql: return "sql";
  }
  return "sql";
}

namespace detail {

namespace {
std::string trimmed(const char* s) {
  std::string m = s ? s : "";
  while (!m.empty() && (m.back() == '\n' || m.back() == ' ')) m.pop_back();
  return m;
}
}  // namespace

PlantError pg_error(PGconn* pg, const PGresult* res, std::string_view what) {
  std::string msg = res ? trimmed(PQresultErrorMessage(res)) : "";
  if (msg.empty()) msg = trimmed(PQerrorMessage(pg));
  const bool gone = PQstatus(pg) == CONNECTION_BAD;
  return {gone ? PlantErrc::connection_lost : PlantErrc::sql,
          std::string(what) + ": " + (gone ? "the plant's server closed the connection: " : "") + msg};
}

}  // namespace detail

using detail::pg_error;

Connection::Connection(std::unique_ptr<detail::Conn> c) : conn_(std::move(c)) {}
Connection::Connection(Connection&&) noexcept = default;
Connection& Connection::operator=(Connection&&) noexcept = default;
Connection::~Connection() = default;

int Connection::socket() const { return PQsocket(conn_->pg); }

PlantResult<void> Connection::exec(const std::string& sql, std::string_view what) {
  PGresult* res = PQexec(conn_->pg, sql.c_str());
  std::unique_ptr<PGresult, decltype(&PQclear)> guard(res, &PQclear);
  const auto st = PQresultStatus(res);
  if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) return std::unexpected(pg_error(conn_->pg, res, what));
  progressed();
  return {};
}

PlantResult<Rows> Connection::query(const std::string& sql, const std::vector<std::optional<std::string>>& params,
                                    std::string_view what) {
  std::vector<const char*> values;
  values.reserve(params.size());
  for (const auto& p : params) values.push_back(p ? p->c_str() : nullptr);
  PGresult* res = PQexecParams(conn_->pg, sql.c_str(), static_cast<int>(values.size()), nullptr, values.data(),
                               nullptr, nullptr, 0);
  std::unique_ptr<PGresult, decltype(&PQclear)> guard(res, &PQclear);
  const auto st = PQresultStatus(res);
  if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) return std::unexpected(pg_error(conn_->pg, res, what));
  progressed();
  Rows out;
  const int nc = PQnfields(res), nr = PQntuples(res);
  for (int c = 0; c < nc; ++c) out.columns.emplace_back(PQfname(res, c));
  out.rows.reserve(static_cast<std::size_t>(nr));
  for (int r = 0; r < nr; ++r) {
    auto& row = out.rows.emplace_back();
    row.reserve(static_cast<std::size_t>(nc));
    for (int c = 0; c < nc; ++c) {
      if (PQgetisnull(res, r, c)) row.emplace_back(std::nullopt);
      else row.emplace_back(std::string(PQgetvalue(res, r, c), static_cast<std::size_t>(PQgetlength(res, r, c))));
    }
  }
  return out;
}

PlantResult<std::int64_t> Connection::copy_in(const std::string& copy_sql, std::string_view data,
                                              std::string_view what) {
  if (auto ok = copy_begin(copy_sql, what); !ok) return std::unexpected(ok.error());
  if (auto ok = copy_put(data, what); !ok) return std::unexpected(ok.error());
  return copy_end(what);
}

PlantResult<void> Connection::copy_begin(const std::string& copy_sql, std::string_view what) {
  PGresult* res = PQexec(conn_->pg, copy_sql.c_str());
  std::unique_ptr<PGresult, decltype(&PQclear)> guard(res, &PQclear);
  if (PQresultStatus(res) != PGRES_COPY_IN) return std::unexpected(pg_error(conn_->pg, res, what));
  progressed();
  return {};
}

PlantResult<void> Connection::copy_put(std::string_view data, std::string_view what) {
  PGconn* pg = conn_->pg;
  // libpq copies each call into its output buffer and writes it out: chunks of 1 MB keep that
  // buffer small and the socket busy.
  constexpr std::size_t kChunk = 1 << 20;
  for (std::size_t off = 0; off < data.size(); off += kChunk) {
    const std::size_t n = std::min(kChunk, data.size() - off);
    if (PQputCopyData(pg, data.data() + off, static_cast<int>(n)) != 1) {
      auto e = pg_error(pg, nullptr, what);
      // Drain whatever result the server left so the connection's state is known.
      while (PGresult* r = PQgetResult(pg)) PQclear(r);
      return std::unexpected(std::move(e));
    }
    progressed();
  }
  return {};
}

PlantResult<std::int64_t> Connection::copy_end(std::string_view what) {
  PGconn* pg = conn_->pg;
  if (PQputCopyEnd(pg, nullptr) != 1) {
    auto e = pg_error(pg, nullptr, what);
    while (PGresult* r = PQgetResult(pg)) PQclear(r);
    return std::unexpected(std::move(e));
  }
  std::optional<PlantError> err;
  std::int64_t rows = 0;
  while (PGresult* res = PQgetResult(pg)) {
    if (PQresultStatus(res) != PGRES_COMMAND_OK) {
      if (!err) err = pg_error(pg, res, what);
    } else {
      rows = std::atoll(PQcmdTuples(res));
    }
    PQclear(res);
    if (PQstatus(pg) == CONNECTION_BAD) break;
  }
  if (!err && PQstatus(pg) == CONNECTION_BAD) err = pg_error(pg, nullptr, what);
  if (err) return std::unexpected(std::move(*err));
  progressed();
  return rows;
}

void copy_escape(std::string& out, std::string_view field) {
  for (char c : field) {
    switch (c) {
      case '\\': out += "\\\\"; break;
      case '\t': out += "\\t"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      default: out += c;
    }
  }
}

std::string check_id(std::string_view value, std::string_view field) {
  if (value.empty()) return std::string(field) + ": empty (expected 1..64 characters)";
  if (value.size() > 64)
    return std::string(field) + ": " + std::to_string(value.size()) + " characters (at most 64)";
  for (std::size_t i = 0; i < value.size(); ++i) {
    const auto c = static_cast<unsigned char>(value[i]);
    if (c < 0x20 || c == 0x7F)
      return std::string(field) + ": a control character at position " + std::to_string(i + 1);
  }
  return {};
}

}  // namespace fogbench::plant
