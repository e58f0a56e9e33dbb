// The automatic analysis when a run completes: each unit's fit or verification computed on the
// offload (the analysis service of analysis.hpp, on fogbenchd's analysis worker), stored and
// noted back on the loop.
#include <csignal>
#include <cstdlib>
#include <memory>

#include "fogbench/daemon/analysis.hpp"
#include "fogbench/daemon/certificate.hpp"
#include "fogbench/daemon/station.hpp"
#include "verdict.hpp"

namespace fogbench::daemon {

using nlohmann::json;

namespace {
// What a unit's analysis computed off the loop: one Commit per axis analysed (x, y, z of a
// three-axis unit; a one-axis unit's single one, with no axis).
struct UnitAxesAnalysis {
  std::vector<std::optional<model::Axis>> axes;
  std::vector<ApiResult<analysis::Commit>> commits;
};
}  // namespace

void Station::analyse(std::int64_t run_id, storage::Purpose purpose,
                      const std::vector<std::string>& serials) {
  std::vector<int> units;
  for (std::size_t i = 0; i < serials.size(); ++i) units.push_back(static_cast<int>(i));
  analyse_units(run_id, purpose, serials, units);
}

void Station::analyse_units(std::int64_t run_id, storage::Purpose purpose, const std::vector<std::string>& serials,
                            const std::vector<int>& units) {
  // Test-only: the daemon dies (SIGKILL) between the run's end and its analysis, so that the
  // e2e tests can restart it on exactly that store (tests/daemon_plans). Never set in service.
  if (const char* k = std::getenv("FOGBENCH_TEST_KILL_BEFORE_ANALYSIS"); k && *k == '1') ::raise(SIGKILL);
  analysing_.insert(run_id);
  // The fits or verifications are computed on the offload (fogbenchd's analysis worker, with its
  // own read connection): a long fit must not hold up the next run's seconds or the replies.
  // What they produced is stored here, on the loop, in unit order, each with its note.
  // The settings the run started with (a reload since applies to later runs only); a run this
  // process did not start (a plan's analysis asked again after a restart) takes the file's.
  const auto started = run_analysis_.find(run_id);
  const AnalysisConfig config = started != run_analysis_.end() ? started->second : config_.analysis;
  const std::string created_at = wall_clock_();
  offload_->submit([this, run_id, purpose, serials, units, config, created_at](storage::Store& reader) -> Offload::Then {
    // A three-axis unit is analysed axis by axis (x, y, z), each against its own model; a
    // one-axis unit (every unit of a run stored before three-axis units) as it always was.
    auto computed = std::make_shared<std::vector<UnitAxesAnalysis>>();
    const auto run_read = reader.get_run(run_id);
    for (const int unit : units) {
      UnitAxesAnalysis ua;
      const bool three = run_read && unit >= 0 && static_cast<std::size_t>(unit) < run_read->run.units.size() &&
                         run_read->run.units[static_cast<std::size_t>(unit)].axes == 3;
      if (three) ua.axes = {model::Axis::x, model::Axis::y, model::Axis::z};
      else ua.axes = {std::nullopt};
      for (const auto axis : ua.axes) {
        try {
          ua.commits.push_back(purpose == storage::Purpose::fit
                                   ? analysis::fit(reader, config, run_id, unit, "", "", created_at, axis)
                                   : analysis::verify(reader, config, run_id, unit, std::nullopt, axis));
        } catch (const std::exception& e) {  // a bug: reported as the unit's failed analysis
          ua.commits.push_back(api_error(ErrorCode::internal, e.what()));
        }
      }
      computed->push_back(std::move(ua));
    }
    return [this, run_id, purpose, serials, units, computed] {
      for (std::size_t k = 0; k < units.size(); ++k) {
        const auto i = static_cast<std::size_t>(units[k]);
        const UnitAxesAnalysis& ua = (*computed)[k];
        json detail = {{"analysis", std::string(storage::to_string(purpose))}, {"unit", units[k]},
                       {"serial", serials[i]}};
        std::vector<ApiResult<json>> stored;
        for (const auto& c : ua.commits) stored.push_back(c ? (*c)(store_) : std::unexpected(c.error()));
        // The unit's result: x's (a one-axis unit's only one); a three-axis unit's analysis fails
        // when any axis' does, naming it, and its axes are in the note's `axes`.
        ApiResult<json> r = stored.front();
        const bool three = ua.axes.size() == 3;
        json axes = json::array();
        if (three) {
          std::optional<ApiError> first_failure;
          for (std::size_t a = 0; a < ua.axes.size(); ++a) {
            const std::string name(model::to_string(*ua.axes[a]));
            json one = {{"axis", name}, {"ok", stored[a].has_value()}};
            if (!stored[a]) {
              one["error"] = stored[a].error().message;
              if (!first_failure) first_failure = ApiError{stored[a].error().code, "axis " + name + ": " + stored[a].error().message};
            } else if (purpose == storage::Purpose::fit) {
              one["model_id"] = (*stored[a])["model_id"];
              one["n_flagged"] = (*stored[a])["n_flagged"];
              if (stored[a]->contains("warning")) one["warning"] = (*stored[a])["warning"];
            } else {
              one["verification_id"] = (*stored[a])["verification_id"];
              one["model_id"] = (*stored[a])["model_id"];
              one["pass"] = (*stored[a])["pass"];
            }
            axes.push_back(std::move(one));
          }
          detail["axes"] = axes;
          if (first_failure) r = std::unexpected(*first_failure);
        }
        if (r && purpose == storage::Purpose::fit) {
          detail["model_id"] = (*r)["model_id"];
          detail["n_flagged"] = (*r)["n_flagged"];
          if (r->contains("warning")) detail["warning"] = (*r)["warning"];
        } else if (r) {
          detail["verification_id"] = (*r)["verification_id"];
          bool pass = (*r)["pass"].get<bool>();
          for (const auto& a : axes) pass = pass && a["pass"].get<bool>();
          detail["pass"] = pass;  // a three-axis unit's: every axis'
          // A bare verify run decides the serial's verdict by the analysis settings; a plan's
          // step leaves it to the plan, decided when the plan is done with the unit.
          auto run = store_.get_run(run_id);
          const auto plan_id = run ? verdict::plan_of_run(*run) : std::nullopt;
          if (plan_id) {
            detail["verdict_by"] = "plan " + std::to_string(*plan_id);
          } else {
            storage::NewVerdict v;
            if (three) {
              std::vector<verdict::AxisVerification> per_axis;
              for (std::size_t a = 0; a < ua.axes.size(); ++a)
                per_axis.push_back({std::string(model::to_string(*ua.axes[a])), (*stored[a])["model_id"].get<std::int64_t>(),
                                    (*stored[a])["result"]});
              v = verdict::from_axis_verifications(serials[i], run_id, units[k], per_axis);
            } else {
              v = verdict::from_verification(serials[i], run_id, units[k], (*r)["model_id"].get<std::int64_t>(),
                                             (*r)["result"]);
            }
            detail["verdict"] = v.verdict;
            try {
              auto cert = decide(v, false);  // queued below, once the run's notes are stored
              if (cert) detail["certificate_sha256"] = *cert;
              else detail["certificate_error"] = cert.error().message;
            } catch (const std::exception& e) {
              detail["certificate_error"] = e.what();
            }
          }
        }
        detail["ok"] = r.has_value();
        if (!r) detail["error"] = r.error().message;
        event(run_id, storage::EventKind::note, detail, std::nullopt);
      }
      // analysing_ keeps the run: notes the store refused wait in the journal (write_or_keep),
      // and the plan runner must wait for them rather than ask for the analysis again.
      // The run, its models and verdicts are all stored: queue it for the plant (issue 14).
      if (config_.plant) queue_for_plant(run_id);
    };
  }, JobOrigin{JobClass::station, {}});
}

ApiResult<std::string> Station::decide(const storage::NewVerdict& v, bool queue_run) {
  if (auto id = store_.put_verdict(v); !id) return std::unexpected(from_store(id.error()));
  // The run is queued for the plant only once its certificate is stored: the plant link takes
  // a queued run at once, and a run sent before its certificate would reach the plant without it.
  auto queue = [&] {
    if (queue_run && config_.plant) queue_for_plant(v.run_id);
  };
  auto body = certificate::build(store_, config_.analysis, config_.station_id, v.serial);
  if (!body) {
    queue();
    return std::unexpected(body.error());
  }
  auto cert = certificate::issue(store_, *body, wall_clock_(), signing_key());
  queue();
  if (!cert) return std::unexpected(cert.error());
  return cert->first["sha256"].get<std::string>();
}

}  // namespace fogbench::daemon
