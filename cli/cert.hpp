// fogctl cert: a serial's certificate from fogbenchd (JSON, or printable HTML with the canonical
// JSON embedded), and --check FILE: whether a certificate is intact (its SHA-256 recomputed)
// and whether the store issued it (docs/cli.md "fogctl cert").
#pragma once

#include <iosfwd>
#include <string>

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
  commands::Common daemon;
};
int run_cert(const CertOptions& o, std::ostream& out, std::ostream& err);
void add_cert_command(CLI::App& app, int& code);

// The printable HTML of a certificate, its canonical JSON embedded in
// <script type="application/json" id="fogbench-certificate">.
std::string certificate_html(const nlohmann::json& cert);
// The certificate JSON in a file's text: the whole text, or the HTML's embedded block.
std::expected<nlohmann::json, std::string> certificate_from_text(const std::string& text);

}  // namespace fogbench::cli
