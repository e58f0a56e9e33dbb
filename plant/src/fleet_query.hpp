// A fleet read over whole tables (internal to plant/src): the planner's nested loops off for
// that one query. Its row estimates for the optional filters ("$1 IS NULL OR ...") are far too
// low, so it picks an index lookup per row (20,000 of them for one figure) where hash joins of
// the tables are 3 times faster (docs/performance.md); the setting is reset after.
#pragma once

#include "fogbench/plant/plant.hpp"

namespace fogbench::plant::detail {

inline PlantResult<Rows> query_scan(Connection& c, const std::string& sql,
                                    const std::vector<std::optional<std::string>>& params, std::string_view what) {
  if (auto ok = c.exec("SET enable_nestloop = off", what); !ok) return std::unexpected(ok.error());
  auto rows = c.query(sql, params, what);
  if (auto ok = c.exec("RESET enable_nestloop", what); !ok && rows) return std::unexpected(ok.error());
  return rows;
}

}  // namespace fogbench::plant::detail
