// bodymodel: one command line, one verb per job. Verbs register themselves (tools/verb.h).
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

#include "core/error.h"
#include "core/io/interrupt_cleanup.h"
#include "core/progress.h"
#include "tools/verb.h"

namespace bodymodel::cli {
std::vector<VerbAdder>& verb_adders() {
  static std::vector<VerbAdder> adders;
  return adders;
}
}  // namespace bodymodel::cli

int main(int argc, char** argv) {
  // Before any verb writes: Ctrl-C or kill then removes the hidden temporaries of the files
  // being written (core/io/interrupt_cleanup.h).
  bodymodel::install_interrupt_cleanup();
  CLI::App app{
      "bodymodel: a statistical model of human bodies from 3D scans, and animated characters.\n"
      "Data is read from $BODYMODEL_DATA (default ../shared/data beside the repository)."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "bodymodel 0.1");
  for (auto& add : bodymodel::cli::verb_adders()) add(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --version: exit 0
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // A malformed command line is bad input like any other: one line, exit 2.
    std::fprintf(stderr, "bodymodel: error: %s (see --help)\n", e.what());
    return 2;
  } catch (const std::filesystem::filesystem_error& e) {
    // A path the file system refuses (a symlink loop, a name too long, permissions): bad input.
    std::string where = e.path1().string();
    std::fprintf(stderr, "bodymodel: error: %s%s\n", where.empty() ? "" : ("'" + where + "': ").c_str(),
                 e.code().message().c_str());
    return 2;
  } catch (const bodymodel::InputError& e) {
    std::fprintf(stderr, "bodymodel: error: %s\n", e.what());
    return 2;
  } catch (const bodymodel::Cancelled&) {
    std::fprintf(stderr, "bodymodel: cancelled\n");
    return 130;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bodymodel: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
