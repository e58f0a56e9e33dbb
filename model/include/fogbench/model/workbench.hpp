// The model workbench (issue 5): see where a drift model fails on runs (compare), learn which
// physical effect is missing (diagnose, over the effects library of shared/TERMS.md), add it
// (add_term) and follow the error falling along a model's lineage. Pure: results are values
// with to_json for the CLI's --json and the daemon's socket.
#pragma once

#include <cstddef>
#include <limits>
#include <expected>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "fogbench/model/model.hpp"

namespace fogbench::model::workbench {

// ---------------------------------------------------------------------------------------
// The effects library: data, not code paths. A new effect is one entry.
struct Effect {
  std::string term;         // in the term language, without lag: "T1", "lp(T1,300)"
  std::string name;         // the physical effect, as a report names it
  std::string explanation;  // one line a gyro engineer would accept
  std::string separated_by; // the profile step on which this term moves unlike its look-alikes
};
const std::vector<Effect>& effects_library();
// The cross-axis entries diagnose adds on a three-axis unit whose axes have their own coil
// thermistors (RunData::has_axis_thermistors): the other two axes' coil temperature and rate
// (`T1y`, `d(T1y)` for an x analysis), coupling inside the housing.
std::vector<Effect> cross_axis_effects(Axis own);
// The library entry of a term (by canonical spelling), if any.
const Effect* find_effect(std::string_view canonical_term);

// ---------------------------------------------------------------------------------------
// compare: a model against a run.
struct CompareOptions {
  // The one noise rule (noise.hpp): an interval fails where the residual's centred
  // noise.smooth_s average stays beyond the yardstick's threshold for noise.max_fail_s or more.
  NoiseRule noise;
  std::expected<void, std::string> validate() const;
};

// A stretch of the run where the model's error stays beyond the threshold.
struct FailInterval {
  Phase phase = Phase::unknown;  // the phase of most of its samples
  int step = -1;                 // the profile step at its start (-1 when not recorded)
  double start_s = 0.0, duration_s = 0.0;
  double mean_err_dph = 0.0;     // mean of measured - predicted over the interval, deg/h
  double peak_err_dph = 0.0;     // smoothed error of largest magnitude (signed), deg/h
  double t1_c = 0.0, t2_c = 0.0; // mean coil temperatures over it, degC
  double ta_c = 0.0;             // mean chamber air, degC (NaN when not recorded)
  double rate_c_per_min = 0.0;   // mean dT1/dt, degC/min
  double grad_c = 0.0;           // mean T1 - T2, degC
};

struct StepTable {
  int step = 0;
  Phase phase = Phase::unknown;  // the phase of most of its samples
  double start_s = 0.0, duration_s = 0.0;
  Table1 stats;
};

struct RunComparison {
  std::string run;                 // the run's name
  std::vector<double> time_s;      // sample times, s
  std::vector<double> measured_dph, predicted_dph, residual_dph;  // deg/h; residual = measured - predicted
  std::vector<double> residual_smooth_dph;  // the residual through the compare smoother, deg/h
  std::vector<double> t1_c, t2_c, ta_c;     // temperatures for plots, degC (ta_c empty when not recorded)
  std::vector<Phase> phase;        // of every sample (derive_phases)
  Verification verification;       // Table 1 of the run and per phase (the core's verify)
  std::vector<StepTable> steps;    // Table 1 per profile step (empty without a step column)
  double threshold_dph = 0.0;      // the yardstick's threshold on the smoothed residual (verification.threshold_dph), deg/h
  std::vector<FailInterval> failures;
  // The noise rule's answer, the same as verify's second test: no failing interval and the
  // compensated std within the gyro's noise floor times its factor.
  bool adequate() const { return failures.empty() && verification.noise_factor <= verification.noise_limit_factor; }
};

std::expected<RunComparison, FitError> compare(const Model& m, const RunData& run, const CompareOptions& o = {});

// ---------------------------------------------------------------------------------------
// diagnose: why a model fails, and which effect of the library is missing.
// Where diagnose is, for a progress line on long runs (DiagnoseOptions::progress).
struct DiagnoseProgress {
  std::string stage;                // "base fit", "bias jumps", "screening", "refitting", "backfitting", "adequacy checks"
  int step = 0;                     // the search's step: 0 the model as given, k after k terms added
  std::size_t done = 0, total = 0;  // candidates done of total in the stage (0 of 0: no count)
};

struct DiagnoseOptions {
  // Called, on the calling thread, as diagnose moves through its stages and candidates (a
  // 3-day run takes seconds): the model does no I/O, fogctl prints it on stderr. Empty: none.
  std::function<void(const DiagnoseProgress&)> progress;
  // A candidate is detected when, refitted with the model, all of these hold:
  double max_delta_bic = -10.0;        // BIC falls by more than 10 ("very strong" on Kass-Raftery's scale)
  double max_p_value = 1e-3;           // its coefficient is significant (two-sided, t from its se)
  double min_fit_fall = 0.02;          // compensated std on the fit run falls by at least 2%
  double min_held_out_fall = 0.01;     // ... and on every held-out run by at least 1%
  double min_fit_fall_alone = 0.05;    // without held-out runs: at least 5% on the fit run
  double max_delta_bic_alone = -40.0;  // ... and BIC falls by more than 40
  // ... or, with held-out runs (issue 25: several effects at once, a run already near its floor
  // cannot fall by 1% while another still carries the effect), over all the runs: BIC and p as
  // above, the error falls by at least min_mean_fall on average over the fit run and every
  // scored held-out run (the greedy step's mean log of after/before), by at least
  // min_fit_fall_pooled on the fit run, and rises on no held-out run by more than max_held_out_rise.
  double min_mean_fall = 0.01;
  double min_fit_fall_pooled = 0.01;
  double max_held_out_rise = 0.005;
  // Two detected candidates are indistinguishable when their columns, with the model's own
  // terms regressed out, correlate beyond this on the fit run and both give a similar fall.
  double collinear_r = 0.95;
  // Look-alikes whose BIC differ by less than this cannot be ranked by the data (6: below
  // "strong" evidence on Kass and Raftery's scale); the library's order ranks them.
  double tie_bic = 6.0;
  int ccf_max_lag_s = 600;             // cross-correlations over lags 0..this, s
  int whiteness_lags = 20;
  std::optional<int> max_lag_s;        // lags searched, s (default: the model's; lower it for short runs)
  // Candidates refitted in parallel (0: up to 4, as the machine has cores). Default 1; more is
  // safe: the core's gamma_q (stats.cpp) uses lgamma_r, not std::lgamma's global signgam.
  int threads = 1;
  int lag_iterations = 4;              // rescans of a candidate's lag after the model's lags move
  // Pruning (docs/performance.md, 2026-11-28): a candidate whose one-column update of the base
  // model (the model's lags held) lowers the fit run's compensated std by less than this
  // fraction of the rule's smallest fit-run fall (min_fit_fall_pooled with held-out runs,
  // min_fit_fall_alone without) is not refitted: a refit's fall was at most 3.8 x its update's
  // on the workbench tests (3,535 refits) and 11.6 x on the 3-day run; 0.05 leaves 1.7 x headroom
  // over the worst. 0: refit every candidate. Second paths (a model term again, whose refit
  // moves the model's lags: up to 6.4 x) and trun (judged by the time-drift test) are always refitted.
  double prune_fraction = 0.05;
  bool second_lags = true;             // also try each model term again at a second lag
  std::vector<std::string> extra_terms;  // further candidates beyond the library (term language)

  // Issue 10: the search over the term language, greedy forward selection, adequacy.
  enum class Search { library, language };
  Search search = Search::language;    // library: the effects library only
  int max_terms = 5;                   // greedy forward selection: terms added at most (1..6)
  int refit_top = 10;                  // generated candidates refitted per step (the best by lag-scan gain)
  int tau_points = 12;                 // lp, d(lp) and warm time constants: a log grid 30 s .. 4 h (2..24 points)
  std::size_t max_candidates = 400;    // a search space larger than this is refused (an error naming it)
  // The samples of all the runs given (the fit run and every held-out run), at most: diagnose's
  // memory grows with them (the fit run's refits and lag scans, each held-out run's scorers; about
  // 1 kB a sample of the fit run at the peak, docs/performance.md), so a larger request is refused
  // before any work (an error naming the runs, their samples and this limit) rather than run the
  // machine into swap. 2,000,000: 23 days at 1 Hz in all, about 2 GB; 1,000 to 100,000,000.
  std::size_t max_samples = 2'000'000;
  // Adequacy (every run given, the model as refitted on the fit run and applied unchanged):
  double adequacy_alpha = 0.01;        // the prewhitened residual passes Ljung-Box at this level,
  // ... or its structure is too small to matter: the RMS of its ACF over the lags,
  // sqrt(Q / (N h)), under this (0.05: a correlated share of about 5% of the residual's
  // variance). On long held-out runs a misfit of 0.03 deg/h is significant (p < 1e-6 on
  // 9300 s) yet harmless; a missing effect at 1.3 x the noise floor gives 0.3 and more.
  double min_acf_rms = 0.05;
  // The noise rule (failing.noise, noise.hpp, the one verify and compare apply): compensated
  // std within the gyro's noise floor times its factor, and no failing interval.
  CompareOptions failing;
  // Bias jumps (a change-point scan of the residual): a step of t >= jump_t and at least
  // jump_min_sigma * sigma_a, estimated with a line and a kink each side over +-jump_window_s.
  bool jumps = true;
  double jump_t = 7.0;
  double jump_min_sigma = 1.0;
  int jump_window_s = 300;
  int max_jumps = 3;                   // per run
  // Drift that is not thermal (docs/workbench.md "Drift that is not thermal"):
  // a trend in time: the base model's residual regressed on the run's own time (trun, h) per
  // run, its slope's standard error from the gyro's noise floor (white, flicker and random walk,
  // read off the holds with each run's line removed); pooled over the runs, |t| >= time_t and
  // the runs' slopes consistent (chi-square p >= 0.001): then trun is a candidate of the search.
  bool time_drift = true;
  double time_t = 5.0;
  // A periodic disturbance: the final residual's periodogram over periods periodic_min_s ..
  // a third of the run, its highest peak against the noise floor's spectrum (and the local
  // level of the periodogram, whichever is higher); found when its chance under that noise,
  // counting every frequency searched, is below periodic_alpha.
  bool periodic = true;
  double periodic_min_s = 60.0;
  double periodic_alpha = 1e-4;
  std::expected<void, std::string> validate() const;
};

struct CrossCorrelation {
  std::string term;                 // canonical spelling
  std::vector<double> r;            // r[i]: prewhitened residual against the term delayed by i s
  double band = 0.0;                // +-2/sqrt(N)
  int peak_lag_s = 0;               // lag of largest |r|
  double peak_r = 0.0;
  int outside = 0;                  // lags outside the band
};

struct HeldOutScore {
  std::string run;
  double rms_before_dph = 0.0, rms_after_dph = 0.0;  // compensated std, deg/h
  bool scored = false;
  std::string skipped;              // why not scored (e.g. the run lacks Ta)
};

struct Candidate {
  std::string term;                 // canonical, with its lag: "T1@12"
  std::string expr;                 // canonical, without lag: "T1"
  std::string effect;               // physical name
  std::string explanation;
  int lag_s = 0;
  bool second_lag = false;          // a model term again at another lag (a second thermal path)
  bool evaluated = false;
  std::string skipped;              // why it was not evaluated
  double rms_before_dph = 0.0, rms_after_dph = 0.0;  // compensated std on the fit run, deg/h
  double fall = 0.0;                // 1 - rms_after/rms_before on the fit run
  double delta_bic = 0.0;           // bic_with - bic_without (lag search counted); negative is better
  double coef = 0.0, se_dph_per_unit = 0.0;  // of the new term, deg/h per unit of the term (see unit)
  std::string unit;
  double t = 0.0, p_value = 1.0;    // t = coef/se, two-sided normal p
  std::vector<HeldOutScore> held_out;
  double held_out_fall = 0.0;       // the smallest fall over scored held-out runs (0 when none)
  bool within_slow_noise = false;   // on some run it removes less variance than the gyro's slow noise
  bool detected = false;
  std::string verdict;              // one line: why detected or not
  std::vector<std::string> collinear_with;  // detected candidates it cannot be told from
  std::string separate_by;          // the profile step that would separate them
};

struct CoefInfo {
  std::string term;                 // "mu0" or the term with its lag
  double coef = 0.0, se_in_unit = 0.0;  // the coefficient and its 1-sigma standard error, in unit
  std::string unit;
};

struct CollinearPair {
  std::string a, b;
  double r = 0.0;                   // correlation of the two coefficients' estimates
  std::string why;
};

// The adequacy checks on one run (docs/workbench.md, "adequate").
struct RunCheck {
  std::string run;
  bool held_out = false;
  bool checked = false;             // false when the model cannot run on it (error says why)
  std::string error;
  double comp_std_dph = 0.0;        // Table 1's compensated std
  double noise_std_dph = 0.0;       // the gyro's noise floor over the run (verify's yardstick), deg/h
  double noise_factor = 0.0;        // comp / noise
  double noise_limit_factor = 0.0;  // the factor allowed (the rule's, or more for slow noise)
  std::string floor_note;           // how the floor was read
  double acf_allowed = 0.0;         // the whiteness test's RMS of the ACF allowed (min_acf_rms + slow noise share)
  double ljung_box_q = 0.0, ljung_box_p = 1.0;  // of the prewhitened residual
  double acf_rms = 0.0;             // sqrt(Q / (N h)): the size of its structure
  // The same whiteness test fails on the residual before the high-pass (run_whiteness with
  // highpass_s 0): structure slower than the test's high-pass, a walk or a slow missed effect.
  // Not a reason of the verdict; the search's backfit takes it as a sign to look further (a
  // first step that left a slow effect behind passes the high-passed test).
  bool slow_structure = false;
  std::vector<FailInterval> failures;
  std::vector<std::string> reasons; // the tests it failed, one line each
};

// A step of the residual that no thermal signal makes: found by the change-point scan.
struct BiasJump {
  std::string run;
  double time_s = 0.0;              // where the step is, s from the run's start
  double size_dph = 0.0;            // after - before, deg/h
  double t = 0.0;                   // size / its standard error
  std::string message;              // "a bias jump of X deg/h at t = Y s: not a thermal effect ..."
};

// A trend in time (ageing of the source, outgassing), not thermal: the residual's slope in the
// run's own time (trun, h since the run's first sample).
struct RunSlope {
  std::string run;
  double slope_dph_per_h = 0.0, se_dph_per_h = 0.0;  // of the base model's residual, deg/h per h
};
// The evidence a report draws: the residual's 61 s average and the line fitted to it.
struct DriftSeries {
  std::string run;
  std::vector<double> time_s, residual_dph, fitted_dph;  // decimated, deg/h
};
struct TimeDrift {
  bool tested = false;
  bool found = false;               // significant against the gyro's noise floor, the runs agree
  bool named = false;               // the search added trun: it beat every thermal term
  bool collinear = false;           // time and temperature cannot be told apart on these runs
  double slope_dph_per_h = 0.0, se_dph_per_h = 0.0, t = 0.0;  // pooled over the runs
  double consistency_p = 1.0;       // chi-square of the runs' slopes about the pooled one
  double r_time_t1 = 0.0;           // correlation of time and T1 (within runs, pooled)
  std::string thermal_term;         // the thermal term the search took instead, if any
  std::vector<RunSlope> runs;
  std::vector<DriftSeries> series;
  std::string message;              // one line for people (empty when not found)
  NoiseFloor floor;                 // the floor the slope was judged against (each run's line removed)
};

// A periodic disturbance: a line in the residual's spectrum above the gyro's noise.
struct PeriodicDisturbance {
  std::string run;
  double period_s = 0.0, amplitude_dph = 0.0;  // of the sinusoid fitted at the peak
  double phase_rad = 0.0;           // amplitude * sin(2 pi t / period + phase), t in s from the run's first sample
  double power_ratio = 0.0;         // the peak's periodogram over the noise expected there
  double p_value = 1.0;             // its chance under the noise, every frequency searched counted
  int frequencies = 0;              // searched
  bool thermal_period = false;      // the temperature program itself swings at this period
  double rms_before_dph = 0.0, rms_after_dph = 0.0;  // residual std, without the sinusoid after
  // The evidence: the periodogram and the noise expected, as amplitude spectra (deg/h: the
  // amplitude a sinusoid at that period would need to give the ordinate), by period.
  std::vector<double> spectrum_period_s, spectrum_amp_dph, noise_amp_dph;
  std::string message;
};

// One step of the greedy forward selection.
struct SearchStep {
  std::string added;                // the term as fitted, with its lag: what `fit --add` takes
  std::string expr, effect;
  bool library = false;             // named by the effects library
  double rms_before_dph = 0.0, rms_after_dph = 0.0;  // fit run
  std::vector<HeldOutScore> held_out;
  std::vector<std::string> look_alikes;
};

struct Diagnosis {
  std::string fit_run;
  std::vector<std::string> held_out_runs;
  std::string model_terms;          // the base model refitted on the fit run
  std::string method;
  bool base_refitted_on_other_run = false;  // the model given was fitted on other data
  double rms_fit_dph = 0.0;         // compensated std of the base model on the fit run
  Whiteness whiteness;              // of the prewhitened residual on the fit run
  std::vector<CoefInfo> coefs;      // of the base model
  std::vector<std::vector<double>> coef_corr;  // [mu0, terms...]
  std::vector<CollinearPair> collinear_coefs;  // |r| > 0.9 among the model's coefficients
  std::vector<CrossCorrelation> ccf;           // one per library term
  std::vector<Candidate> candidates;           // best first: detected by fall, then the rest
  bool adequate = true;             // no candidate detected and every run passes the checks
  std::vector<std::string> reasons; // why not adequate, one line per failed test
  std::vector<RunCheck> checks;     // the adequacy checks of the model, per run (fit run first)
  std::vector<BiasJump> jumps;      // found on any run (removed from that run only for the search)
  TimeDrift time_drift;             // a trend in time (tested on the base model's residual)
  std::vector<PeriodicDisturbance> periodic;  // found on the final residual, per run
  std::string search = "language";  // library | language
  nlohmann::json search_space;      // what the search tried: signals, transforms, taus, counts, limit
  std::vector<SearchStep> steps;    // the greedy selection: terms added, in order
  std::string final_terms;          // the model's terms with the steps added
  std::vector<RunCheck> final_checks;  // the adequacy checks after the steps
  bool outside_search = false;      // something remains that nothing in the search explains
  std::string residual_follows;     // what the remaining residual follows: ton, T1, d(T1) or none
  std::string rule;                 // the detection rule in words
  std::string summary;              // one paragraph for people
};

// A run's name and length, for the size check.
struct RunSize {
  std::string name;
  std::size_t samples = 0;
};
// diagnose's size check on the runs' names and lengths (the fit run first, then the held-out
// runs), so that it is tested without such runs: an error naming the runs, their samples and the
// limit when they hold more than max_samples in all (the largest named first).
std::expected<void, std::string> check_diagnose_size(std::span<const RunSize> runs, std::size_t max_samples);

// Diagnoses `m` (its terms refitted on `fit_run` with its method and options) against the
// library; held-out runs score each candidate's refitted model unchanged. Runs holding more than
// o.max_samples in all are refused (FitError::Code::bad_options, check_diagnose_size's message).
std::expected<Diagnosis, FitError> diagnose(const Model& m, const RunData& fit_run, std::span<const RunData> held_out,
                                            const DiagnoseOptions& o = {});

// The non-thermal tests alone (diagnose runs them): a trend in time of m's residual over the
// runs, and a periodic disturbance of m's residual on one run (empty when none is found).
TimeDrift time_drift(const Model& m, std::span<const RunData> runs, const DiagnoseOptions& o = {});
std::optional<PeriodicDisturbance> find_periodic(const Model& m, const RunData& run, const DiagnoseOptions& o = {});

// ---------------------------------------------------------------------------------------
// add: the model's terms plus one, refitted with the same method and options on a run.
// `term` in the term language; `@auto` with the paper method (one shared lag) is resolved by
// the lag scan of the model's residual, so the new term does not move the paper's lag. The
// model's own @auto lags are refitted, unless the refit runs one to the edge of its scan: then
// they are kept at their fitted values (notes says so).
struct AddResult {
  Model model;                      // parent and note set; created_at left to the caller
  std::string added;                // the term as fitted, with its lag
  // What the refit did that its user should know: the model's lags kept where they were when
  // the refit ran one to the edge of its scan (model::lags_at_edge). Also in model.note.
  std::vector<std::string> notes;
};
std::expected<AddResult, FitError> add_term(const Model& m, const RunData& run, std::string_view term);

// The model's fit options (method, lags, smoothing) as recorded in it.
FitOptions options_of(const Model& m);
// The model's terms as typed for a refit: fitted lags of @auto terms become @auto again.
TermList terms_of(const Model& m);

// ---------------------------------------------------------------------------------------
// lineage: the error of each model of the chain on each run, root first.
struct LineageStep {
  std::string terms;
  std::string note;
  std::string created_at;
  std::string fitted_on;
  std::vector<double> comp_std_dph;   // per run, NaN where the model cannot run (message in errors)
  std::vector<std::string> errors;    // per run, empty when fine
};
struct Lineage {
  std::vector<std::string> runs;
  std::vector<LineageStep> steps;
};
Lineage lineage(const Model& m, std::span<const RunData> runs);

// ---------------------------------------------------------------------------------------
// The qualification summary in the terms of IEEE Std 952-1997 (thermal sensitivities).
struct Sensitivity {
  std::string term, unit;
  double coef = 0.0, se_in_unit = 0.0;  // in unit; the standard error 1 sigma
};
struct QualRun {
  std::string run;
  bool held_out = false;
  double meas_std_dph = 0.0, comp_std_dph = 0.0, ratio = 0.0;
  double hysteresis_dph = std::numeric_limits<double>::quiet_NaN();       // heating - cooling at equal T1, raw output
  double hysteresis_comp_dph = std::numeric_limits<double>::quiet_NaN();  // the same after compensation
  double peak_ramp_excursion_dph = 0.0;  // largest |smoothed output - mu0| on ramps
  Verdict verdict = Verdict::fail;  // verify's: pass, marginal (ratio passed, second test not), fail
  std::vector<std::string> reasons; // why not pass
  bool pass = false;                // verdict == pass
};
struct Qualification {
  std::vector<Sensitivity> sensitivities;
  double mu0_dph = 0.0, mu0_se_dph = 0.0;
  std::vector<QualRun> runs;
  double threshold = 0.2;
  bool pass = false;                // every run's verdict is pass
  bool marginal = false;            // no run fails, but some run is marginal
};
Qualification qualify(const Model& m, std::span<const RunData> runs, std::span<const bool> held_out, double threshold = 0.2);

// ---------------------------------------------------------------------------------------
nlohmann::json to_json(const FailInterval& f);
nlohmann::json to_json(const RunComparison& c, bool with_series = false);
nlohmann::json to_json(const Candidate& c);
nlohmann::json to_json(const Diagnosis& d);
nlohmann::json to_json(const RunCheck& c);
nlohmann::json to_json(const TimeDrift& t);
nlohmann::json to_json(const PeriodicDisturbance& p);
nlohmann::json to_json(const Lineage& l);
nlohmann::json to_json(const Qualification& q);

// Helpers shared with the report: at most `max_points` samples of a series, keeping the
// extremes of each bucket so that peaks survive (min and max per bucket, in time order).
std::vector<std::size_t> decimate_indices(std::span<const double> y, std::size_t max_points);
// Centred moving average of width w samples (shrunk at the ends).
std::vector<double> moving_average(std::span<const double> x, int w);

}  // namespace fogbench::model::workbench
