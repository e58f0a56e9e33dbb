// The libpq connection behind plant::Connection (internal to plant/src).
#pragma once

#include <libpq-fe.h>

#include <string>

#include "fogbench/plant/plant.hpp"

namespace fogbench::plant::detail {

struct Conn {
  PGconn* pg = nullptr;
  ~Conn() {
    if (pg) PQfinish(pg);
  }
};

// PostgreSQL's message for the last failure, trimmed, and whether the connection is gone.
PlantError pg_error(PGconn* pg, const PGresult* res, std::string_view what);

}  // namespace fogbench::plant::detail
