// fogctl's plan and queue commands (docs/plans.md, docs/cli.md): plan validate|start|status|
// abort|report and queue list|add|remove|move, over the daemon client.
#pragma once

#include <ostream>

#include <nlohmann/json.hpp>

namespace CLI {
class App;
}

namespace fogbench::cli {

void add_plan_commands(CLI::App& app, int& code);

// The plan's exit code: 0 every unit passed, 3 some marginal and none failed, 1 a unit failed,
// 2 the plan did not complete (aborted, failed).
int plan_exit_code(const nlohmann::json& status);
// One HTML page for the whole plan: its steps and runs, each unit's verdict and every
// measurement against its limit. `status` is plan.status's result.
std::string plan_report_html(const nlohmann::json& status);

}  // namespace fogbench::cli
