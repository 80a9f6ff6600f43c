// The `bodymodel` command line: each verb lives in tools/verbs/<verb>.cc (dashes as underscores;
// `skin` sub-verbs in skin_<verb>.cc; encode, decode and interpolate share one file) and registers
// itself with BODYMODEL_VERB, so adding a verb never edits main.cc. A verb parses its options,
// calls the library (or a tools/pipeline/ job) and writes its outputs; algorithms live in the
// libraries, where Python reaches them too.
//
//   BODYMODEL_VERB(add_encode_verb) {           // receives CLI::App& app
//     auto* cmd = app.add_subcommand("encode", "Encode meshes ...");
//     auto opts = std::make_shared<Options>();
//     cmd->add_option(...);
//     cmd->callback([opts] { ... });            // throw bodymodel::InputError for bad input
//   }
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

namespace bodymodel::cli {

using VerbAdder = std::function<void(CLI::App&)>;
std::vector<VerbAdder>& verb_adders();

struct VerbRegistrar {
  explicit VerbRegistrar(VerbAdder adder) { verb_adders().push_back(std::move(adder)); }
};

}  // namespace bodymodel::cli

#define BODYMODEL_VERB(fn)                                                       \
  static void fn(CLI::App& app);                                                 \
  static const ::bodymodel::cli::VerbRegistrar fn##_registrar{&fn};              \
  static void fn(CLI::App& app)
