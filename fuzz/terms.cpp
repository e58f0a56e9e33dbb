// Fuzzes the term language (model/include/fogbench/model/terms.hpp): the whole input is a term
// list as a user types it (`fogctl fit --terms`, the daemon's model.fit "terms"). A text gives a
// TermList or a ParseError with a position inside the text. A TermList's canonical spelling
// (to_string) must parse again and print the same: it is how terms are compared and stored.
// Every term is evaluated over a short synthetic run.
#include <cmath>
#include <string>
#include <vector>

#include "common.hpp"
#include "fogbench/model/terms.hpp"

using namespace fogbench::model;

namespace {

// Four minutes at 1 Hz: longer than the derivative window (61 samples), so d() and dd() take
// both their edge and their interior paths. T1 and T2 lag a sine excursion of the air.
struct Synthetic {
  static constexpr std::size_t n = 240;
  std::vector<double> t1, t2, ta, ton;
  std::vector<double> y1, y2, z1, z2;  // the y and z axes' own coils, deeper in the housing (T1y..T2z)
  Synthetic() {
    for (std::size_t i = 0; i < n; ++i) {
      const double t_s = static_cast<double>(i);
      ton.push_back(600.0 + t_s);
      ta.push_back(5.0 * std::sin(t_s / 40.0));
      t2.push_back(4.0 * std::sin((t_s - 10.0) / 40.0));
      t1.push_back(3.0 * std::sin((t_s - 30.0) / 40.0) + 0.01 * static_cast<double>(i % 7));
      y2.push_back(3.5 * std::sin((t_s - 20.0) / 40.0));
      y1.push_back(2.5 * std::sin((t_s - 45.0) / 40.0));
      z2.push_back(3.0 * std::sin((t_s - 30.0) / 40.0));
      z1.push_back(2.0 * std::sin((t_s - 60.0) / 40.0));
    }
  }
};

void check_evaluate(const Expr& e) {
  static const Synthetic syn;
  const Signals with_ta{syn.t1, syn.t2, syn.ta, 1.0, syn.ton, {syn.t1, syn.y1, syn.z1}, {syn.t2, syn.y2, syn.z2}};
  auto v = evaluate(e, with_ta);
  FUZZ_CHECK(v.has_value(), "evaluation failed with every signal present: %s", v.error().c_str());
  FUZZ_CHECK(v->size() == Synthetic::n, "%zu values for %zu samples", v->size(), Synthetic::n);

  // Without the chamber's air: only a term that reads Ta may fail.
  const Signals without_ta{syn.t1, syn.t2, {}, 1.0, syn.ton, with_ta.axis_t1, with_ta.axis_t2};
  auto w = evaluate(e, without_ta);
  FUZZ_CHECK(w.has_value() || uses_signal(e, Signal::Ta), "failed without Ta but does not use it: %s",
             w.error().c_str());
  if (w) FUZZ_CHECK(w->size() == Synthetic::n, "%zu values for %zu samples", w->size(), Synthetic::n);

  // Without per-axis thermistors (a unit whose axes share them): only a cross-axis term may fail.
  const Signals shared{syn.t1, syn.t2, syn.ta, 1.0, syn.ton};
  auto x = evaluate(e, shared);
  FUZZ_CHECK(x.has_value() || uses_axis_thermistor(e), "failed without per-axis thermistors but reads none: %s",
             x.error().c_str());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto text = fogbench::fuzz::as_text(data, size);
  auto list = parse_terms(text);
  if (!list) {
    FUZZ_CHECK(list.error().position <= text.size(), "error position %zu beyond the text (%zu bytes)",
               list.error().position, text.size());
    FUZZ_CHECK(!list.error().message.empty(), "an error without a message");
    (void)list.error().pretty();
    return 0;
  }
  FUZZ_CHECK(!list->terms.empty(), "a parsed list without terms");

  const std::string canonical = to_string(*list);
  auto again = parse_terms(canonical);
  FUZZ_CHECK(again.has_value(), "the canonical spelling does not parse: '%s': %s", canonical.c_str(),
             again.error().pretty().c_str());
  const std::string twice = to_string(*again);
  FUZZ_CHECK(twice == canonical, "canonical spelling not stable: '%s' parses and prints as '%s'",
             canonical.c_str(), twice.c_str());
  FUZZ_CHECK(again->terms.size() == list->terms.size(), "%zu terms became %zu", list->terms.size(),
             again->terms.size());

  for (const auto& t : list->terms) {
    FUZZ_CHECK(t.expr != nullptr, "a term without an expression");
    (void)coef_unit(*t.expr);
    (void)to_string(t, false);
    // parse_term of a single term's spelling gives that term back.
    const std::string one = to_string(t);
    auto single = parse_term(one);
    FUZZ_CHECK(single.has_value(), "a term's spelling '%s' does not parse alone", one.c_str());
    FUZZ_CHECK(to_string(*single) == one, "term '%s' parses alone as '%s'", one.c_str(),
               to_string(*single).c_str());
    check_evaluate(*t.expr);
  }
  return 0;
}
