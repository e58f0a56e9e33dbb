// fogctl report: placeholder until the HTML report lands.
#include <ostream>

#include "workbench.hpp"

namespace fogbench::cli {
int run_report(const ReportOptions&, std::ostream&, std::ostream& err) {
  err << "fogctl report: not built yet\n";
  return kExitError;
}
}  // namespace fogbench::cli
