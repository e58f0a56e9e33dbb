// fogctl cert: a serial's certificate from fogbenchd (JSON, or printable HTML rendered from the
// signed JSON, which it embeds), --public-key: the station's public key, and --check FILE --key
// station.pub: whether a certificate is valid, offline (its Ed25519 signature, and for the HTML
// its visible tables re-rendered from the embedded JSON), docs/cli.md "fogctl cert".
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "client_commands.hpp"

namespace CLI {
class App;
}

namespace fogbench::cli {

struct CertOptions {
  std::string serial;
  std::string output;  // -o FILE: .json writes the canonical JSON, anything else HTML
  std::string check;   // --check FILE
  std::vector<std::string> keys;  // --key FILE|DIR, repeatable: public keys (keyrings) to check with
  std::string revoked;  // --revoked FILE: revoked key ids with their dates
  bool public_key = false;  // --public-key: the station's public key from the daemon
  commands::Common daemon;
};
int run_cert(const CertOptions& o, std::ostream& out, std::ostream& err);
void add_cert_command(CLI::App& app, int& code);

// The printable HTML of a certificate, its canonical JSON embedded in
// <script type="application/json" id="fogbench-certificate">. Deterministic: --check renders
// the embedded JSON again and compares the page's visible part with it.
std::string certificate_html(const nlohmann::json& cert);
// The same page as layout `page` (2, 3 or 4: cli/cert.cpp says what each draws) drew it, byte
// for byte: --check compares an issued page with the layout that drew it.
std::string certificate_html(const nlohmann::json& cert, int page);
// Whether an HTML page's visible part (all but the embedded JSON) is what `cert` renders to:
// "" when it is, else where it differs. A page of another renderer version cannot be compared:
// std::unexpected saying so.
std::expected<std::string, std::string> visible_difference(const std::string& html, const nlohmann::json& cert);
// The certificate JSON in a file's text: the whole text, or the HTML's embedded block.
std::expected<nlohmann::json, std::string> certificate_from_text(const std::string& text);

}  // namespace fogbench::cli
