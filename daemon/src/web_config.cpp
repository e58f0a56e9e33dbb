// The `web` section of fogbenchd's configuration (docs/web.md): where the web panel and the
// metrics listen. Loopback unless the configuration says allow_remote, since the panel's reads
// need no token.
#include "fogbench/daemon/config.hpp"
#include "config_fields.hpp"

#include <boost/asio/ip/address.hpp>
#include <algorithm>
#include <cctype>
#include <fstream>
#include <optional>

namespace fogbench::daemon {

using nlohmann::json;

std::expected<WebConfig, std::string> parse_web_config(const json& j, const std::filesystem::path& base_dir) {
  using Err = std::unexpected<std::string>;
  if (!j.is_object())
    return Err("web: expected an object {\"listen\": \"127.0.0.1:8080\", \"allow_remote\"?, \"enabled\"?, \"token_file\"?, \"hosts\"?}");
  if (auto ok = config_fields::only_keys(j, "web", config_fields::kWebKeys); !ok)
    return Err(ok.error());
  WebConfig w;
  if (j.contains("enabled")) {
    if (!j["enabled"].is_boolean()) return Err("web.enabled: expected true or false");
    w.enabled = j["enabled"].get<bool>();
  }
  if (j.contains("token_file")) {
    if (!j["token_file"].is_string() || j["token_file"].get<std::string>().empty())
      return Err("web.token_file: expected a file name");
    // Read only when the panel is on: a sample with it off passes --check-config before the
    // file is made.
    if (w.enabled) {
      const std::string f = j["token_file"].get<std::string>();
      const std::filesystem::path path = std::filesystem::path(f).is_absolute() ? std::filesystem::path(f) : base_dir / f;
      std::ifstream in(path);
      std::string line;
      if (!in || !std::getline(in, line)) return Err("web.token_file: cannot be read: " + path.string());
      while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
      if (line.empty()) return Err("web.token_file: the first line is empty: " + path.string());
      if (line.size() < 16) return Err("web.token_file: the token is shorter than 16 characters: " + path.string());
      w.token = line;
    }
  }
  if (j.contains("hosts")) {
    const auto bad = Err("web.hosts: expected an array of host names, e.g. [\"bench7.plant.example\"]");
    if (!j["hosts"].is_array()) return bad;
    for (const auto& h : j["hosts"]) {
      if (!h.is_string()) return bad;
      std::string name = h.get<std::string>();
      // A name, without a scheme, a port or a path: the Host header's port is the listener's.
      if (name.empty() || name.find_first_of(":/ []@") != std::string::npos)
        return Err("web.hosts: \"" + name + "\" is not a host name (no scheme, port or path)");
      std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return std::tolower(c); });
      w.hosts.push_back(std::move(name));
    }
  }
  if (j.contains("allow_remote")) {
    if (!j["allow_remote"].is_boolean()) return Err("web.allow_remote: expected true or false");
    w.allow_remote = j["allow_remote"].get<bool>();
  }
  if (!j.contains("listen")) return Err("web.listen: missing (e.g. \"127.0.0.1:8080\")");
  if (!j["listen"].is_string()) return Err("web.listen: expected a string \"address:port\"");
  const std::string listen = j["listen"].get<std::string>();
  // "host:port" or "[v6]:port".
  std::string host, port;
  if (!listen.empty() && listen.front() == '[') {
    const auto close = listen.find(']');
    if (close == std::string::npos || close + 1 >= listen.size() || listen[close + 1] != ':')
      return Err("web.listen: expected \"[address]:port\" for IPv6, got \"" + listen + "\"");
    host = listen.substr(1, close - 1);
    port = listen.substr(close + 2);
  } else {
    const auto colon = listen.rfind(':');
    if (colon == std::string::npos) return Err("web.listen: expected \"address:port\", got \"" + listen + "\"");
    host = listen.substr(0, colon);
    port = listen.substr(colon + 1);
  }
  boost::system::error_code ec;
  const auto addr = boost::asio::ip::make_address(host, ec);
  if (ec) return Err("web.listen: not an IP address: \"" + host + "\"");
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
      std::stoul(port) > 65535)
    return Err("web.listen: expected a port 0..65535 after the address, got \"" + port + "\"");
  if (!addr.is_loopback() && !w.allow_remote)
    return Err("web.listen: " + host +
               " is not a loopback address; the panel's reads need no token, so serving other hosts needs "
               "\"allow_remote\": true");
  w.address = host;
  w.port = static_cast<std::uint16_t>(std::stoul(port));
  return w;
}

namespace {

// The host of a Host header or of an Origin's authority, without its port and brackets, in
// lower case; nullopt when it is not of the form name[:port] or [v6][:port].
std::optional<std::string> host_part(std::string_view authority) {
  std::string host;
  if (!authority.empty() && authority.front() == '[') {
    const auto close = authority.find(']');
    if (close == std::string_view::npos) return std::nullopt;
    if (close + 1 < authority.size() && authority[close + 1] != ':') return std::nullopt;
    host = authority.substr(1, close - 1);
  } else {
    const auto colon = authority.find(':');
    if (colon != std::string_view::npos && authority.find(':', colon + 1) != std::string_view::npos) return std::nullopt;
    host = authority.substr(0, colon);
  }
  std::transform(host.begin(), host.end(), host.begin(), [](unsigned char c) { return std::tolower(c); });
  return host;
}

bool host_allowed(const WebConfig& w, const std::string& host) {
  if (host.empty()) return false;
  // An address: the browser's origin is the address itself, which no other site can claim.
  boost::system::error_code ec;
  boost::asio::ip::make_address(host, ec);
  if (!ec || host == "localhost") return true;
  return std::find(w.hosts.begin(), w.hosts.end(), host) != w.hosts.end();
}

}  // namespace

bool web_host_allowed(const WebConfig& w, std::string_view host_header) {
  // No Host at all is no browser (HTTP/1.1 browsers always send it): nothing to rebind.
  if (host_header.empty()) return true;
  const auto host = host_part(host_header);
  return host && host_allowed(w, *host);
}

bool web_origin_allowed(const WebConfig& w, std::string_view origin, std::string_view host_header) {
  if (origin.empty()) return true;
  const auto scheme = origin.find("://");
  if (scheme == std::string_view::npos) return false;
  const std::string_view authority = origin.substr(scheme + 3);
  // The page's own origin, and a name of this panel.
  if (authority != host_header) return false;
  const auto host = host_part(authority);
  return host && host_allowed(w, *host);
}

}  // namespace fogbench::daemon
