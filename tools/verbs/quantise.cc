// bodymodel quantise model.npz --out small.npz [--bits 8] [--block-rows 64] [--samples 20] [--max-error-mm 0.5]
#include <fmt/format.h>

#include <filesystem>

#include "core/error.h"
#include "model/model_file.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

struct QuantiseArgs {
  std::string model, out;
  int bits = 8, block_rows = 64, samples = 20;
  double max_error_mm = 0.5;
};

void run_quantise(const QuantiseArgs& a) {
  namespace fs = std::filesystem;
  if (a.samples < 1) throw InputError(fmt::format("--samples must be ≥ 1, got {}", a.samples));
  if (fs::exists(a.out) && fs::equivalent(a.model, a.out))
    throw InputError("--out must not be the input model (write a new file, then move it)");
  BodyModel model = model_cli::load_model_for_cli(a.model);
  const ModelFileOptions storage =
      model_cli::choose_basis_storage(model, a.bits, a.block_rows, a.samples, a.max_error_mm);
  save_model(a.out, model, storage);
  const auto in_bytes = fs::file_size(a.model), out_bytes = fs::file_size(a.out);
  cli::info(fmt::format("wrote {} ({} bases): {:.2f} MB, was {:.2f} MB ({:.1f} %); {} + {} components, shape "
                        "and full model",
                        a.out, storage.basis_bits == 32 ? std::string("float32") : fmt::format("{}-bit", storage.basis_bits),
                        out_bytes / 1e6, in_bytes / 1e6, 100.0 * static_cast<double>(out_bytes) / static_cast<double>(in_bytes),
                        model.shape.component_count(), model.full.component_count()));
}

}  // namespace

BODYMODEL_VERB(add_model_quantise_verb) {
  auto a = std::make_shared<QuantiseArgs>();
  auto* cmd = app.add_subcommand(
      "quantise",
      "Rewrite a model file with its PCA bases stored as 8- or 16-bit integers (a scale per block of\n"
      "rows of each component), or back to float32 (--bits 32). Every verb and the Python module read\n"
      "either. Before writing, --samples random bodies (coefficients within the training data's range)\n"
      "are decoded through both bases; if any vertex moves by more than --max-error-mm, 16 bits and then\n"
      "float32 are used instead. The check is printed and kept in the file's metadata\n"
      "(quantisation_check). See docs/model.md for sizes and errors.\n"
      "Example: bodymodel quantise model.npz --out model-q8.npz --bits 8");
  cmd->add_option("model", a->model, "Model (.npz)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out", a->out, "Output model (.npz)")->required();
  cmd->add_option("--bits", a->bits, "8 or 16 (integers), 32 (float32)")
      ->check(CLI::IsMember({8, 16, 32}))
      ->capture_default_str();
  cmd->add_option("--block-rows", a->block_rows,
                  "Rows of a basis column sharing one scale (a large value: one scale per component)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--samples", a->samples, "Random bodies decoded both ways for the check")->capture_default_str();
  cmd->add_option("--max-error-mm", a->max_error_mm,
                  "Largest vertex distance allowed between the bodies decoded both ways (mm)")
      ->capture_default_str();
  cmd->callback([a] { run_quantise(*a); });
}

}  // namespace bodymodel
