// A checking parser of the Prometheus text exposition format 0.0.4, for the metrics tests: every
// line a HELP, a TYPE or a sample; names and label names by the format's grammar; label values
// unescaped (\\, \", \n, nothing else); TYPE and HELP once per family and before its samples; a
// counter's name ends in _total; no series twice. Problems are collected with their line number.
#pragma once

#include <cmath>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace fogbench::web_test {

struct Sample {
  std::string name;
  std::map<std::string, std::string> labels;
  double value = 0.0;
};

struct Exposition {
  std::map<std::string, std::string> help, type;
  std::vector<Sample> samples;
  std::vector<std::string> errors;

  // The samples of `name` whose labels include `with`.
  std::vector<Sample> find(const std::string& name, const std::map<std::string, std::string>& with = {}) const {
    std::vector<Sample> out;
    for (const auto& s : samples) {
      if (s.name != name) continue;
      bool ok = true;
      for (const auto& [k, v] : with)
        if (!s.labels.contains(k) || s.labels.at(k) != v) ok = false;
      if (ok) out.push_back(s);
    }
    return out;
  }
};

inline bool parse_value(const std::string& t, double& v) {
  if (t == "NaN") return v = NAN, true;
  if (t == "+Inf" || t == "Inf") return v = INFINITY, true;
  if (t == "-Inf") return v = -INFINITY, true;
  static const std::regex num(R"([-+]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][-+]?[0-9]+)?)");
  if (!std::regex_match(t, num)) return false;
  v = std::stod(t);
  return true;
}

inline Exposition parse_exposition(const std::string& text) {
  Exposition e;
  static const std::regex name_re("[a-zA-Z_:][a-zA-Z0-9_:]*");
  static const std::regex label_re("[a-zA-Z_][a-zA-Z0-9_]*");
  if (!text.empty() && text.back() != '\n') e.errors.push_back("the text does not end with a newline");
  std::istringstream in(text);
  std::string line;
  int n = 0;
  std::map<std::string, bool> seen_sample;
  std::map<std::string, int> series;
  auto err = [&](const std::string& what) { e.errors.push_back("line " + std::to_string(n) + ": " + what + ": " + line); };
  while (std::getline(in, line)) {
    ++n;
    if (line.empty()) continue;
    if (line[0] == '#') {
      std::istringstream l(line.substr(1));
      std::string kw, name, rest;
      l >> kw >> name;
      std::getline(l, rest);
      if (!rest.empty() && rest[0] == ' ') rest.erase(0, 1);
      if (kw != "HELP" && kw != "TYPE") continue;  // a comment
      if (!std::regex_match(name, name_re)) err("bad metric name");
      if (seen_sample[name]) err(kw + " after the family's samples");
      auto& m = kw == "HELP" ? e.help : e.type;
      if (m.contains(name)) err(kw + " twice");
      if (kw == "TYPE" && rest != "counter" && rest != "gauge" && rest != "histogram" && rest != "summary" && rest != "untyped")
        err("unknown type");
      if (kw == "TYPE" && rest == "counter" && !(name.size() > 6 && name.ends_with("_total"))) err("a counter not named _total");
      m[name] = rest;
      continue;
    }
    Sample s;
    std::size_t i = 0;
    while (i < line.size() && line[i] != '{' && line[i] != ' ') ++i;
    s.name = line.substr(0, i);
    if (!std::regex_match(s.name, name_re)) err("bad metric name");
    if (i < line.size() && line[i] == '{') {
      ++i;
      while (i < line.size() && line[i] != '}') {
        std::size_t eq = line.find('=', i);
        if (eq == std::string::npos) { err("label without ="); break; }
        const std::string ln = line.substr(i, eq - i);
        if (!std::regex_match(ln, label_re)) err("bad label name '" + ln + "'");
        i = eq + 1;
        if (i >= line.size() || line[i] != '"') { err("label value not quoted"); break; }
        ++i;
        std::string v;
        bool closed = false;
        while (i < line.size()) {
          const char c = line[i++];
          if (c == '"') { closed = true; break; }
          if (c == '\\') {
            if (i >= line.size()) break;
            const char d = line[i++];
            if (d == '\\') v += '\\';
            else if (d == '"') v += '"';
            else if (d == 'n') v += '\n';
            else err(std::string("bad escape \\") + d);
          } else {
            v += c;
          }
        }
        if (!closed) { err("label value not closed"); break; }
        if (s.labels.contains(ln)) err("label twice");
        s.labels[ln] = v;
        if (i < line.size() && line[i] == ',') ++i;
      }
      if (i >= line.size() || line[i] != '}') { err("labels not closed"); continue; }
      ++i;
    }
    if (i >= line.size() || line[i] != ' ') { err("no value"); continue; }
    std::string rest = line.substr(i + 1);
    const auto sp = rest.find(' ');  // an optional timestamp
    if (!parse_value(rest.substr(0, sp), s.value)) err("bad value");
    if (!e.type.contains(s.name)) err("a sample without TYPE");
    if (!e.help.contains(s.name)) err("a sample without HELP");
    seen_sample[s.name] = true;
    std::string key = s.name;
    for (const auto& [k, v] : s.labels) key += "|" + k + "=" + v;
    if (series[key]++) err("a series twice");
    e.samples.push_back(std::move(s));
  }
  return e;
}

}  // namespace fogbench::web_test
