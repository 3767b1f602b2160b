// maglead: the command line of the magnetic lead-screw actuator controller and its twin.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "cli_common.hpp"

namespace {

using maglead::cli::closest_match;

std::string path_of(const CLI::App* app) {
  std::string s;
  for (; app; app = app->get_parent())
    if (!app->get_name().empty()) s = app->get_name() + (s.empty() ? "" : " " + s);
  return s;
}

std::vector<std::string> subcommand_names(const CLI::App* app) {
  std::vector<std::string> out;
  for (const auto* sub :
       app->get_subcommands([](const CLI::App* s) { return !s->get_name().empty(); }))
    out.push_back(sub->get_name());
  return out;
}

/// Long option names of an app, its option groups and (options fall through) its parents.
std::vector<std::string> option_names(const CLI::App* app) {
  std::vector<std::string> out;
  for (; app; app = app->get_parent()) {
    std::vector<const CLI::App*> scopes{app};
    for (const auto* g :
         app->get_subcommands([](const CLI::App* s) { return s->get_name().empty(); }))
      scopes.push_back(g);
    for (const auto* scope : scopes)
      for (const auto* opt : scope->get_options())
        for (const auto& n : opt->get_lnames()) out.push_back("--" + n);
  }
  return out;
}

bool knows_option(const CLI::App* app, const std::string& name) {
  for (; app; app = app->get_parent())
    if (app->get_option_no_throw(name)) return true;
  return false;
}

bool is_number(const std::string& text) {
  char* end = nullptr;
  std::strtod(text.c_str(), &end);
  return end != text.c_str() && *end == '\0';
}

/// After a parse error: the first unknown command or option in argv, answered with the closest
/// match and the usage line. False when argv holds neither (CLI11's own message is better then).
bool explain_unknown(CLI::App& root, int argc, char** argv) {
  const CLI::App* at = &root;
  bool expect_value = false;  // the previous token was an option that takes a value
  for (int i = 1; i < argc; ++i) {
    const std::string tok = argv[i];
    if (tok == "--") break;
    if (expect_value && is_number(tok)) {  // `--min-gain -5`: a value, as CLI11 takes it
      expect_value = false;
      continue;
    }
    // `--hold -1s`: CLI11 reads a negative value with a unit as the options -1 -s.
    if (expect_value && tok.size() > 1 && tok[0] == '-' &&
        (std::isdigit(static_cast<unsigned char>(tok[1])) || tok[1] == '.')) {
      std::fprintf(stderr,
                   "maglead: error: %s %s: the value must be positive (e.g. %s %s)\nrun '%s "
                   "--help' for the options\n",
                   argv[i - 1], tok.c_str(), argv[i - 1], tok.c_str() + 1, path_of(at).c_str());
      return true;
    }
    if (tok.size() > 1 && tok[0] == '-') {
      expect_value = false;
      std::string name = tok.substr(0, tok.find('='));
      if (name.rfind("--", 0) != 0 && name.size() > 2) name = name.substr(0, 2);  // -abc: short -a
      if (knows_option(at, name)) {
        const CLI::App* scope = at;
        const CLI::Option* opt = nullptr;
        for (; scope && !opt; scope = scope->get_parent()) opt = scope->get_option_no_throw(name);
        expect_value = opt && opt->get_type_size_max() > 0 && tok.find('=') == std::string::npos;
        continue;
      }
      const std::string guess = closest_match(name, option_names(at));
      std::fprintf(stderr,
                   "maglead: unknown option '%s' for '%s'%s\nusage: %s [OPTIONS]   ('%s --help' "
                   "lists them)\n",
                   name.c_str(), path_of(at).c_str(),
                   guess.empty() ? "" : ("; did you mean '" + guess + "'?").c_str(),
                   path_of(at).c_str(), path_of(at).c_str());
      return true;
    }
    if (expect_value) {
      expect_value = false;
      continue;
    }
    const auto names = subcommand_names(at);
    if (names.empty()) continue;  // a positional value of a leaf command
    const auto subs = at->get_subcommands(
        [&](const CLI::App* s) { return !s->get_name().empty() && s->check_name(tok); });
    if (!subs.empty()) {
      at = subs.front();
      continue;
    }
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
    // `maglead help`, `maglead version`: the words other tools take, meant as the flags.
    std::string guess = closest_match(tok, names);
    if (tok == "help") guess = "--help";
    if (tok == "version" && at == &root) guess = "--version";
    // The command list on its own line, wrapped on a terminal as every error is.
    std::fprintf(stderr, "%s\n",
                 maglead::cli::error_text(
                     "maglead: unknown command '" + tok + "'" +
                     (guess.empty() ? "" : "; did you mean '" + path_of(at) + " " + guess + "'?") +
                     "\nusage: " + path_of(at) + " COMMAND [OPTIONS]   ('" + path_of(at) +
                     " --help' says what each does)\ncommands: " + list)
                     .c_str());
    return true;
  }
  return false;
}

/// A usage error (a missing or invalid option): the documented exit code 2, the message with
/// the `maglead: error:` prefix, and what to type for the command's options.
void usage_error(const CLI::App& root, const CLI::ParseError& e) {
  const CLI::App* at = &root;
  for (auto subs = at->get_subcommands(); !subs.empty(); subs = at->get_subcommands())
    at = subs.front();
  std::fprintf(stderr, "%s\nrun '%s --help' for the options\n",
               maglead::cli::error_text(std::string("maglead: error: ") + e.what()).c_str(),
               path_of(at).c_str());
}

/// One help line at most `width` columns, broken at spaces, each continuation under the line's
/// description: in an entry (2 columns in, 4 in an option group) where CLI11 padded the name to
/// `column`; in a line of its own deeper in (a description under a name too long for the
/// column, or a list inside one), at its start or past its first run of two spaces; else two
/// columns in.
std::string wrap_help_line(const std::string& line, std::size_t width, std::size_t column) {
  constexpr std::size_t kLeastDescription = 24;  // a narrower column reads worse than a wide one
  constexpr std::size_t kEntryIndent = 4;        // an option group's entries sit 2 deeper
  const std::size_t lead = line.find_first_not_of(' ');
  if (lead == std::string::npos) return line;
  std::size_t desc = std::string::npos;
  const std::size_t padded = lead + column - 2;  // CLI11 counts the entry's 2 columns in
  if (lead >= 2 && lead <= kEntryIndent && padded < line.size() && line[padded - 1] == ' ' &&
      line[padded] != ' ')
    desc = padded;
  const std::size_t gap = line.find("  ", lead);
  if (desc == std::string::npos && gap != std::string::npos)
    desc = line.find_first_not_of(' ', gap);
  else if (desc == std::string::npos && lead > kEntryIndent)
    desc = lead;
  std::size_t indent = lead + 2;
  if (desc != std::string::npos && desc + kLeastDescription <= width) indent = desc;
  return maglead::cli::wrapped(line, indent, width);
}

/// A command's line in its parent's list: its description up to the first clause break (". ",
/// "; ", ": ", " ("), shortened at its last ", " or " and " while it would take more than two
/// lines at 80 columns beside `column`; `maglead COMMAND --help` gives the whole.
std::string summary_of(const std::string& description, std::size_t column) {
  constexpr std::size_t kWidth = 80;  // the narrowest terminal the list is kept short for
  constexpr std::size_t kMostLines = 2;
  std::size_t end = description.size();
  for (const char* brk : {". ", "; ", ": ", " ("}) end = std::min(end, description.find(brk));
  std::string text = description.substr(0, end);
  const auto lines = [&](const std::string& t) {
    const std::string w = maglead::cli::wrapped(t, 0, kWidth - column);
    return 1 + static_cast<std::size_t>(std::count(w.begin(), w.end(), '\n'));
  };
  while (lines(text) > kMostLines) {
    std::size_t cut = 0;
    for (const char* brk : {", ", " and "})
      if (const std::size_t at = text.rfind(brk); at != std::string::npos) cut = std::max(cut, at);
    if (cut == 0) break;
    text.resize(cut);
  }
  return text;
}

/// The width --help wraps to: $COLUMNS when it is a number, as for ls and man (`COLUMNS=80
/// maglead analyze --help | less` asks for 80 columns in a pipe too), else the terminal's, else 0.
std::size_t help_columns() {
  if (const char* columns = std::getenv("COLUMNS")) {
    char* end = nullptr;
    const long n = std::strtol(columns, &end, 10);
    if (end != columns && *end == '\0' && n > 0) return static_cast<std::size_t>(n);
  }
  return maglead::cli::terminal_columns();
}

/// CLI11 2.1 does not wrap its help: at 80 columns a terminal broke descriptions mid-word. Each
/// line is wrapped to help_columns(); into a pipe without $COLUMNS (man page, scripts) lines stay
/// whole.
class WrappingFormatter : public CLI::Formatter {
 public:
  std::string make_subcommand(const CLI::App* sub) const override {
    std::stringstream out;
    CLI::detail::format_help(out, sub->get_display_name(true),
                             summary_of(sub->get_description(), get_column_width()),
                             get_column_width());
    return out.str();
  }

  std::string make_help(const CLI::App* app, std::string name,
                        CLI::AppFormatMode mode) const override {
    std::string text = CLI::Formatter::make_help(app, std::move(name), mode);
    const std::size_t width = help_columns();
    if (width == 0) return text;
    std::string out;
    std::size_t pos = 0;
    while (pos < text.size()) {
      const std::size_t end = std::min(text.find('\n', pos), text.size());
      out += wrap_help_line(text.substr(pos, end - pos), width, get_column_width()) + "\n";
      pos = end + 1;
    }
    return out;
  }
};

/// The sentence of --help that points to the man page, for where this binary runs: a build
/// tree's page (BIN/../man, which man(1) does not search) by its path, an installed one
/// (BIN/../share/man/man1) by name under /usr or /usr/local (man's own path) and by its path
/// elsewhere, and "" when the build made none (no help2man).
std::string man_pointer() {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path bin = fs::read_symlink("/proc/self/exe", ec).parent_path();
  if (ec) return "";
  const fs::path prefix = fs::weakly_canonical(bin / "..", ec);
  for (const fs::path& page :
       {prefix / "man/maglead.1.gz", prefix / "share/man/man1/maglead.1.gz"}) {
    if (!fs::exists(page, ec)) continue;
    if (page.parent_path().filename() == "man1" && (prefix == "/usr" || prefix == "/usr/local"))
      return " See man maglead for every command.";
    // Relative to the working directory when under it (`man -l build/man/maglead.1.gz` in a
    // checkout); from / the whole path reads better.
    const fs::path cwd = fs::current_path(ec);
    const fs::path shown = page.lexically_proximate(cwd);
    const bool under = cwd != cwd.root_path() && !shown.empty() && *shown.begin() != "..";
    return " See man -l " + (under ? shown : page).string() + " for every command.";
  }
  return "";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "maglead: force-estimating controller for a magnetic lead-screw actuator, with its "
      "simulated plant and digital twin.\nRun 'maglead COMMAND --help' for a command's options." +
          man_pointer(),
      "maglead"};
  app.formatter(std::make_shared<WrappingFormatter>());  // before the commands: they inherit it
  app.set_version_flag("--version", "maglead " MAGLEAD_VERSION, "Print the version and exit");
  app.add_flag(
      "-q,--quiet", maglead::cli::quiet(),
      "No progress or notes on stderr (results and errors still print); progress is only ever "
      "drawn when stderr is a terminal");
  app.require_subcommand(1);
  app.fallthrough();
  maglead::cli::register_all(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::RuntimeError& e) {
    return app.exit(e);  // a command's own exit code; its message is already printed
  } catch (const CLI::ParseError& e) {
    if (!explain_unknown(app, argc, argv)) usage_error(app, e);
    return maglead::cli::kExitBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n",
                 maglead::cli::error_text(std::string("maglead: error: ") + e.what() +
                                          maglead::cli::missing_config_hint(e.what()))
                     .c_str());
    return maglead::cli::kExitBadInput;
  }
  return 0;
}
