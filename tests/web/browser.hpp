// Headless Chromium driven over its DevTools protocol (a WebSocket, from the Beast client of
// web_client.hpp), for the panel's tests (web_chromium_test.cpp, web_plan_panel_test.cpp).
#pragma once

#include <cstdlib>
#include <cstring>
#include <fstream>

#include "../daemon/live_bench.hpp"
#include "web_client.hpp"

namespace fogbench::web_test {

using fogbench::daemon::test::Process;
using fogbench::daemon::test::SteadyClock;
using nlohmann::json;

// FOGBENCH_CHROMIUM names the browser (a path that does not exist: the test reports SKIPPED,
// which is how the skip itself is checked).
inline std::string find_chromium() {
  if (const char* c = std::getenv("FOGBENCH_CHROMIUM")) return std::filesystem::exists(c) ? c : "";
  for (const char* c : {"/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome"})
    if (std::filesystem::exists(c)) return c;
  return {};
}

// Headless Chromium on `url` with a fresh profile and the DevTools protocol on a port it picks.
class Browser {
 public:
  Browser(const std::string& exe, const std::filesystem::path& dir, const std::string& url) : profile_(dir / "chrome") {
    std::filesystem::create_directories(profile_);
    proc_ = std::make_unique<Process>(
        std::vector<std::string>{exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                                 "--user-data-dir=" + profile_.string(), "--remote-debugging-port=0",
                                 "--window-size=1200,1600", url},
        dir / "chrome.log");
    // Chromium writes the port it took into DevToolsActivePort.
    const auto deadline = SteadyClock::now() + 60s;
    while (SteadyClock::now() < deadline && port_ == 0) {
      std::ifstream f(profile_ / "DevToolsActivePort");
      int p = 0;
      if (f >> p) port_ = static_cast<std::uint16_t>(p);
      else std::this_thread::sleep_for(100ms);
    }
    if (!port_) return;
    // The page's target.
    for (int i = 0; i < 100 && !page_; ++i) {
      auto list = json::parse(http_get(port_, "/json/list").body, nullptr, false);
      if (list.is_array())
        for (const auto& t : list)
          if (t.value("type", "") == "page") {
            const std::string u = t.value("webSocketDebuggerUrl", "");
            const auto path = u.find("/devtools/");
            if (path != std::string::npos) page_ = std::make_unique<WsClient>("127.0.0.1", port_, u.substr(path));
            break;
          }
      if (!page_) std::this_thread::sleep_for(100ms);
    }
  }
  bool ok() const { return page_ && page_->ok(); }

  // A JavaScript expression's value in the page (promises awaited); null when it threw.
  json eval(const std::string& expr) {
    auto r = page_->call({{"method", "Runtime.evaluate"},
                          {"params", {{"expression", expr}, {"returnByValue", true}, {"awaitPromise", true}}}});
    if (!r.is_object() || !r.contains("result") || r["result"].contains("exceptionDetails")) return nullptr;
    return r["result"]["result"].value("value", json(nullptr));
  }
  // A DevTools command's result (an object; null when it failed), e.g.
  // cdp("Emulation.setEmulatedMedia", {{"media", "print"}}).
  json cdp(const std::string& method, json params = json::object()) {
    auto r = page_->call({{"method", method}, {"params", std::move(params)}});
    if (!r.is_object() || !r.contains("result")) return nullptr;
    return r["result"];
  }
  // A PNG of the page (Page.captureScreenshot), empty when it failed.
  std::string screenshot() {
    auto r = cdp("Page.captureScreenshot", {{"format", "png"}});
    return r.is_object() ? decode_base64(r.value("data", "")) : std::string();
  }
  // The page printed to a PDF (Page.printToPDF, A4 portrait), empty when it failed.
  std::string pdf() {
    auto r = cdp("Page.printToPDF", {{"paperWidth", 8.27}, {"paperHeight", 11.69}, {"printBackground", true}});
    return r.is_object() ? decode_base64(r.value("data", "")) : std::string();
  }
  static std::string decode_base64(const std::string& b64) {
    std::string out;
    int val = 0, bits = -8;
    for (unsigned char ch : b64) {
      const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
      const char* p = std::strchr(table, ch);
      if (!p || ch == 0) break;
      val = (val << 6) + static_cast<int>(p - table);
      bits += 6;
      if (bits >= 0) {
        out.push_back(static_cast<char>((val >> bits) & 0xff));
        bits -= 8;
      }
    }
    return out;
  }
  // Polls a boolean expression until it holds or the deadline passes.
  bool until(const std::string& expr, std::chrono::seconds timeout) {
    const auto deadline = SteadyClock::now() + timeout;
    while (SteadyClock::now() < deadline) {
      if (eval(expr) == true) return true;
      std::this_thread::sleep_for(250ms);
    }
    return false;
  }

 private:
  std::filesystem::path profile_;
  std::unique_ptr<Process> proc_;
  std::uint16_t port_ = 0;
  std::unique_ptr<WsClient> page_;
};

}  // namespace fogbench::web_test
