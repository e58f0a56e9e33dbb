// fogctl's command table turned into what a Linux tool ships: the list of its commands (for the
// man page, generated from each command's --help at build time by cmake/manpage.cmake) and its
// bash and zsh completion (CLI11 generates neither). Hidden: `fogctl __generate
// commands|bash|zsh`, run by the build (cli/CMakeLists.txt), not by users.
#include <CLI/CLI.hpp>
#include <iostream>
#include <string>
#include <vector>

#include "client.hpp"

namespace fogbench::cli {

namespace {

struct Command {
  std::string path;                   // "run start"
  std::vector<std::string> subs;      // its subcommands' names
  std::vector<std::string> options;   // --long and -s names, flags and options alike
  std::vector<std::string> descriptions;  // one per option, for zsh
};

void walk(const CLI::App* app, const std::string& path, std::vector<Command>& out) {
  Command c;
  c.path = path;
  for (const CLI::App* s : app->get_subcommands([](const CLI::App* a) { return !a->get_group().empty(); }))
    c.subs.push_back(s->get_name());
  for (const CLI::Option* o : app->get_options()) {
    std::string desc = o->get_description();
    for (auto& ch : desc)
      if (ch == '\n' || ch == '\'' || ch == ':' || ch == '[' || ch == ']') ch = ' ';
    for (const auto& l : o->get_lnames()) {
      c.options.push_back("--" + l);
      c.descriptions.push_back(desc);
    }
    for (const auto& s : o->get_snames()) {
      c.options.push_back("-" + s);
      c.descriptions.push_back(desc);
    }
  }
  out.push_back(c);
  for (const CLI::App* s : app->get_subcommands([](const CLI::App* a) { return !a->get_group().empty(); }))
    walk(s, path.empty() ? s->get_name() : path + " " + s->get_name(), out);
}

std::string words(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& w : v) s += (s.empty() ? "" : " ") + w;
  return s;
}

void bash(const std::vector<Command>& table, std::ostream& out) {
  out << "# bash completion for fogctl, generated from its command table (fogctl __generate bash)\n"
         "_fogctl() {\n"
         "  local cur=${COMP_WORDS[COMP_CWORD]} cmdpath=\"\" w i\n"
         "  # The command path: the words before the cursor that name subcommands.\n"
         "  for ((i = 1; i < COMP_CWORD; i++)); do\n"
         "    w=${COMP_WORDS[i]}\n"
         "    case \"$cmdpath|$w\" in\n";
  for (const auto& c : table)
    for (const auto& s : c.subs) out << "      \"" << c.path << "|" << s << "\") cmdpath=\"" << (c.path.empty() ? s : c.path + " " + s) << "\" ;;\n";
  out << "    esac\n"
         "  done\n"
         "  local subs=\"\" opts=\"\"\n"
         "  case \"$cmdpath\" in\n";
  for (const auto& c : table)
    out << "    \"" << c.path << "\") subs=\"" << words(c.subs) << "\"; opts=\"" << words(c.options) << "\" ;;\n";
  out << "  esac\n"
         "  if [[ $cur == -* ]]; then\n"
         "    COMPREPLY=($(compgen -W \"$opts\" -- \"$cur\"))\n"
         "  elif [[ -n $subs ]]; then\n"
         "    COMPREPLY=($(compgen -W \"$subs\" -- \"$cur\"))\n"
         "  else\n"
         "    COMPREPLY=($(compgen -f -- \"$cur\"))\n"
         "  fi\n"
         "}\n"
         "complete -o filenames -F _fogctl fogctl\n";
}

void zsh(const std::vector<Command>& table, std::ostream& out) {
  out << "#compdef fogctl\n"
         "# zsh completion for fogctl, generated from its command table (fogctl __generate zsh)\n"
         "_fogctl() {\n"
         "  local cmdpath=\"\" w i\n"
         "  for ((i = 2; i < CURRENT; i++)); do\n"
         "    w=${words[i]}\n"
         "    case \"$cmdpath|$w\" in\n";
  for (const auto& c : table)
    for (const auto& s : c.subs) out << "      \"" << c.path << "|" << s << "\") cmdpath=\"" << (c.path.empty() ? s : c.path + " " + s) << "\" ;;\n";
  out << "    esac\n"
         "  done\n"
         "  case \"$cmdpath\" in\n";
  for (const auto& c : table) {
    out << "    \"" << c.path << "\")\n";
    if (!c.subs.empty()) out << "      [[ ${words[CURRENT]} != -* ]] && { compadd -- " << words(c.subs) << "; return }\n";
    out << "      _arguments -s";
    for (std::size_t i = 0; i < c.options.size(); ++i) out << " '" << c.options[i] << "[" << c.descriptions[i] << "]'";
    out << " '*:file:_files' ;;\n";
  }
  out << "  esac\n"
         "}\n"
         "_fogctl \"$@\"\n";
}

}  // namespace

void add_generate_command(CLI::App& app, int& code) {
  static std::string what;
  auto* g = app.add_subcommand("__generate", "The command table for the build: commands, bash or zsh");
  g->group("");  // hidden from --help
  g->add_option("what", what, "commands, bash or zsh")->required()->check(CLI::IsMember({"commands", "bash", "zsh"}));
  g->callback([&app, &code] {
    std::vector<Command> table;
    walk(&app, "", table);
    std::erase_if(table, [](const Command& c) { return c.path.starts_with("__generate"); });
    for (auto& c : table) std::erase(c.subs, std::string("__generate"));
    if (what == "commands") {
      for (const auto& c : table)
        if (!c.path.empty()) std::cout << c.path << "\n";
    } else if (what == "bash") {
      bash(table, std::cout);
    } else {
      zsh(table, std::cout);
    }
    code = 0;
  });
}

}  // namespace fogbench::cli
