// Benchmark: a certificate (issue 13, point 2; target under 100 ms): certificate::build on a
// store holding a serial's 6 h fit run and 6 h verify run (21,600 samples each: the coil's
// temperatures through a heat-cool cycle, the paper's drift plus white noise), its model and the
// verification, then the canonical JSON and its SHA-256. Includes reading both runs' records
// and the verify run's samples, the compensation and the Allan deviation. CPU time of the thread
// (the store is in memory: no I/O waits), median of 11.
// Then (issue 24, target under 5 ms each) signing that certificate with the station's Ed25519
// key (the canonical JSON, its SHA-256 and the signature: signing::sign_certificate, what the
// daemon adds to each issue), and verifying it as `fogctl cert --check` does: the JSON file's
// text parsed and its signature checked; the HTML page's embedded JSON read, its visible part
// drawn again and compared, the signature checked. Median of 101 each.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <random>
#include <vector>

#include "fogbench/daemon/certificate.hpp"
#include "fogbench/model/json.hpp"
#include "fogbench/model/model.hpp"
#include "fogbench/model/terms.hpp"
#include "fogbench/signing/certificate.hpp"
#include "fogbench/storage/runs.hpp"
#include "fogbench/storage/samples.hpp"
#include "fogbench/storage/store.hpp"
#include "fogbench/storage/models.hpp"
#include "cert.hpp"
#include <openssl/opensslv.h>

using namespace fogbench;

namespace {

model::RunData synthetic_run(std::uint64_t seed, int n) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.05);
  model::RunData d;
  d.name = "bench";
  double t1 = 20.0, t2 = 20.0, air = 20.0;
  for (int k = 0; k < n; ++k) {
    const double sp = 20.0 + 15.0 * std::sin(2.0 * M_PI * k / 7200.0);
    air += std::clamp(sp - air, -0.05, 0.05);
    const double t1_old = t1;
    t2 += (air - t2) / 60.0;
    t1 += (0.5 * (t2 + air) - t1) / 240.0;
    d.time_s.push_back(k);
    d.t1_c.push_back(t1);
    d.t2_c.push_back(t2);
    d.gyro_dph.push_back(-8.0 - 2.7 * (t1 - t1_old) * 60.0 - 0.4 * (t1 - t2) + noise(rng));
  }
  return d;
}

double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

void fail(const std::string& why) {
  std::fprintf(stderr, "bench_certificate: %s\n", why.c_str());
  std::exit(1);
}

}  // namespace

int main() {
  constexpr int n = 21600;
  auto store = storage::Store::open(":memory:");
  if (!store) fail(store.error().message);
  const auto fit_run = synthetic_run(1, n), verify_run = synthetic_run(2, n);
  storage::ImportOptions o;
  o.serial = "FOG-BENCH";
  auto fit_id = store->import_run(fit_run, o);
  o.purpose = storage::Purpose::verify;
  auto verify_id = store->import_run(verify_run, o);
  if (!fit_id || !verify_id) fail("import");
  auto terms = model::parse_terms("paper");
  if (!terms) fail("terms");
  auto m = model::fit(fit_run, *terms);
  if (!m) fail("fit: " + m.error().message);
  auto ref = store->put_model({"FOG-BENCH", *fit_id, std::nullopt, model::to_json(*m).dump(), "paper", m->terms_string()});
  if (!ref) fail(ref.error().message);
  auto v = model::verify(*m, verify_run);
  if (!v) fail("verify: " + v.error().message);
  if (!store->put_verification({*verify_id, 0, ref->id, model::to_json(*v).dump(), v->pass})) fail("put_verification");

  const daemon::AnalysisConfig limits;
  std::vector<double> ms;
  std::string hash;
  for (int rep = 0; rep < 11; ++rep) {
    const double t0 = cpu_ms();
    auto body = daemon::certificate::build(*store, limits, "bench", "FOG-BENCH");
    if (!body) fail(body.error().message);
    nlohmann::json cert = *body;
    cert["issued_at"] = "2026-11-25T09:00:00Z";
    hash = daemon::certificate::hash_of(cert);
    ms.push_back(cpu_ms() - t0);
  }
  std::sort(ms.begin(), ms.end());
  std::printf("certificate of a serial with a %d-sample fit run and a %d-sample verify run: %.1f ms "
              "(median of 11; min %.1f, max %.1f; target 100 ms) sha256 %.12s...\n",
              n, n, ms[5], ms.front(), ms.back(), hash.c_str());

  auto body = daemon::certificate::build(*store, limits, "bench", "FOG-BENCH");
  if (!body) fail(body.error().message);
  nlohmann::json unsigned_cert = *body;
  unsigned_cert["issued_at"] = "2026-11-25T09:00:00Z";
  auto key = signing::SigningKey::generate();
  if (!key) fail(key.error());
  const std::vector<signing::PublicKey> keys{key->public_key()};
  constexpr int reps = 101;
  std::vector<double> sign_ms, json_ms, html_ms;
  std::size_t json_bytes = 0, html_bytes = 0;
  for (int rep = 0; rep < reps; ++rep) {
    nlohmann::json c = unsigned_cert;
    double t0 = cpu_ms();
    if (auto ok = signing::sign_certificate(c, *key, "bench"); !ok) fail(ok.error());
    sign_ms.push_back(cpu_ms() - t0);
    const std::string text = c.dump(), html = cli::certificate_html(c);
    json_bytes = text.size();
    html_bytes = html.size();
    t0 = cpu_ms();
    const auto parsed = nlohmann::json::parse(text);
    if (signing::check_certificate(parsed, keys).exit_code != 0) fail("the signed certificate does not verify");
    json_ms.push_back(cpu_ms() - t0);
    t0 = cpu_ms();
    auto from_page = cli::certificate_from_text(html);
    if (!from_page) fail(from_page.error());
    auto diff = cli::visible_difference(html, *from_page);
    if (!diff || !diff->empty()) fail("the page's visible part differs from its JSON");
    if (signing::check_certificate(*from_page, keys).exit_code != 0) fail("the page's certificate does not verify");
    html_ms.push_back(cpu_ms() - t0);
  }
  for (auto* times : {&sign_ms, &json_ms, &html_ms}) std::sort(times->begin(), times->end());
  std::printf("sign (Ed25519, OpenSSL %s) a %zu-byte certificate: %.3f ms; verify its JSON: %.3f ms; verify its "
              "%zu-byte HTML page (visible tables redrawn and compared): %.3f ms (medians of %d; max %.3f, %.3f, %.3f; "
              "target 5 ms)\n",
              OPENSSL_VERSION_STR, json_bytes, sign_ms[reps / 2], json_ms[reps / 2], html_bytes, html_ms[reps / 2], reps,
              sign_ms.back(), json_ms.back(), html_ms.back());
  return 0;
}
