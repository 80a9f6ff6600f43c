// bodymodel quantise model.npz --out small.npz [--bits auto|2..16|32] [--max-mb M] [--block-rows 64] [--samples 20]
//     [--max-error-mm 0.5]
// bodymodel quantise model.npz --compare small.npz [--samples 100] [--seed 1000]: decoded bodies, both files
#include <fmt/format.h>

#include <filesystem>
#include <stdexcept>

#include "core/error.h"
#include "model/model_file.h"
#include "model/quantise.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

struct QuantiseArgs {
  std::string model, out, compare;
  uint64_t seed = 1000;
  std::string bits = "auto";
  int block_rows = 64, samples = 20, min_bits = kMinBasisBits;
  double max_error_mm = 0.5, max_mb = 0;
};

// Checks a file someone else quantised (or this verb, with other random bodies than it chose
// with): exit 1 if a vertex moves by more than the bound.
void run_compare(const QuantiseArgs& a) {
  const BodyModel reference = model_cli::load_model_for_cli(a.model);
  const BodyModel other = model_cli::load_model_for_cli(a.compare);
  if (other.shape.pca.basis.rows() != reference.shape.pca.basis.rows() ||
      other.shape.component_count() != reference.shape.component_count() ||
      other.full.component_count() != reference.full.component_count())
    throw InputError(fmt::format("{}: not a quantised copy of {} (other topology or component counts)", a.compare,
                                 a.model));
  const QuantisationError e = decoded_body_difference(reference, other, a.samples, a.seed);
  cli::info(fmt::format("{} against {} (seed {}): {}", a.compare, a.model, a.seed, e.report()));
  if (e.max_mm > a.max_error_mm)
    throw std::runtime_error(fmt::format("{}: a decoded vertex moves {:.4f} mm, over --max-error-mm {}", a.compare,
                                         e.max_mm, a.max_error_mm));
}

void run_quantise(const QuantiseArgs& a) {
  namespace fs = std::filesystem;
  if (a.samples < 1) throw InputError(fmt::format("--samples must be ≥ 1, got {}", a.samples));
  if (!a.compare.empty()) return run_compare(a);
  if (a.out.empty()) throw InputError("--out (the file to write) or --compare (a file to check) is required");
  if (fs::exists(a.out) && fs::equivalent(a.model, a.out))
    throw InputError("--out must not be the input model (write a new file, then move it)");
  const int bits = a.bits == "auto" ? 0 : std::stoi(a.bits);
  if (a.max_mb < 0 || (a.max_mb > 0 && bits != 0))
    throw InputError(fmt::format("--max-mb {} needs --bits auto (per-column widths) and a size > 0", a.max_mb));
  BodyModel model = model_cli::load_model_for_cli(a.model);
  const ModelFileOptions storage =
      model_cli::choose_basis_storage(model, bits, a.block_rows, a.samples, a.max_error_mm, a.max_mb, a.min_bits);
  save_model(a.out, model, storage);
  const auto in_bytes = fs::file_size(a.model), out_bytes = fs::file_size(a.out);
  if (a.max_mb > 0 && static_cast<double>(out_bytes) > a.max_mb * 1e6)
    cli::warn(fmt::format("{} is {:.2f} MB, over --max-mb {} (the estimate was low)", a.out, out_bytes / 1e6, a.max_mb));
  const std::string how = storage.basis_bits == 32                                        ? std::string("float32")
                          : storage.shape_column_bits.size() > 0 && bits == 0 ? std::string("per-column")
                                                                                : fmt::format("{}-bit", storage.basis_bits);
  cli::info(fmt::format("wrote {} ({} bases): {:.2f} MB, was {:.2f} MB ({:.1f} %); {} + {} components, shape "
                        "and full model",
                        a.out, how,
                        out_bytes / 1e6, in_bytes / 1e6, 100.0 * static_cast<double>(out_bytes) / static_cast<double>(in_bytes),
                        model.shape.component_count(), model.full.component_count()));
}

}  // namespace

BODYMODEL_VERB(add_model_quantise_verb) {
  auto a = std::make_shared<QuantiseArgs>();
  auto* cmd = app.add_subcommand(
      "quantise",
      "Rewrite a model file with its PCA bases stored as integers (a scale per block of rows of each\n"
      "component), or back to float32 (--bits 32). --bits auto (default) gives each component 2 to 16 bits\n"
      "by its effect on decoded bodies: the smallest file that passes the check, or with --max-mb the\n"
      "lowest error within that size. Every verb and the Python module read either. Before writing,\n"
      "--samples random bodies (coefficients within the training data's range) are decoded through both\n"
      "bases; if any vertex moves by more than --max-error-mm, 16 bits and then float32 are used instead\n"
      "(with --max-mb: nothing is written). The check and size are printed and kept in the file's\n"
      "metadata (quantisation_check). See docs/model.md for sizes and errors.\n"
      "--compare FILE writes nothing: it decodes --samples random bodies (--seed) through both files.\n"
      "Example: bodymodel quantise model.npz --out model-q.npz --max-mb 150");
  cmd->add_option("model", a->model, "Model (.npz)")->required()->check(CLI::ExistingFile);
  auto* out = cmd->add_option("--out", a->out, "Output model (.npz)");
  cmd->add_option("--compare", a->compare,
                  "A quantised copy of the model to check instead of writing one: the largest and mean vertex "
                  "distance of --samples random bodies decoded through both; exit 1 over --max-error-mm")
      ->check(CLI::ExistingFile)
      ->excludes(out);
  cmd->add_option("--bits", a->bits, "auto (2 to 16 per component), 8 or 16 (8: 16 for the components that need it), 32 (float32)")
      ->check(CLI::IsMember({"auto", "8", "16", "32"}))
      ->capture_default_str();
  cmd->add_option("--max-mb", a->max_mb, "With --bits auto: a size budget (MB = 10^6 bytes); the lowest error within it")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--min-bits", a->min_bits, "With --bits auto: the fewest bits a component gets")
      ->check(CLI::Range(kMinBasisBits, kMaxBasisBits))
      ->capture_default_str();
  cmd->add_option("--block-rows", a->block_rows,
                  "Rows of a basis column sharing one scale (a large value: one scale per component)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--samples", a->samples, "Random bodies decoded both ways for the check")->capture_default_str();
  cmd->add_option("--seed", a->seed, "With --compare: the random bodies' seed")->capture_default_str();
  cmd->add_option("--max-error-mm", a->max_error_mm,
                  "Largest vertex distance allowed between the bodies decoded both ways (mm)")
      ->capture_default_str();
  cmd->callback([a] { run_quantise(*a); });
}

}  // namespace bodymodel
