// Helpers shared by the model verbs (build, morph, generate, pose, edit).
#pragma once

#include <fmt/format.h>

#include <cmath>
#include <string>
#include <utility>

#include "core/error.h"
#include "model/body_model.h"
#include "model/model_file.h"
#include "model/quantise.h"
#include "tools/console.h"

namespace bodymodel::model_cli {

// "name=value" → (name, value); InputError naming the option otherwise.
inline std::pair<std::string, std::string> split_assignment(const std::string& s, const std::string& option) {
  auto eq = s.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == s.size())
    throw InputError(fmt::format("{} expects LABEL=VALUE, got '{}'", option, s));
  return {s.substr(0, eq), s.substr(eq + 1)};
}

inline double parse_number(const std::string& s, const std::string& what) {
  char* end = nullptr;
  double v = std::strtod(s.c_str(), &end);
  if (s.empty() || !end || *end != '\0' || !std::isfinite(v))
    throw InputError(fmt::format("{}: '{}' is not a number", what, s));
  return v;
}

// Value of a label given on the command line ("sex" also accepts female/male).
inline double parse_label_value(const std::string& label, const std::string& s) {
  if (label == "sex") {
    if (s == "female" || s == "f") return 0;
    if (s == "male" || s == "m") return 1;
  }
  return parse_number(s, "value of '" + label + "'");
}

// Warns (and clamps when asked) when `value` is far outside the training data of `info`.
inline double check_label_range(const LabelInfo& info, double value, bool clamp) {
  const double range = info.max - info.min;
  const double lo = info.min - 0.25 * range, hi = info.max + 0.25 * range;
  if (value >= lo && value <= hi) return value;
  if (clamp) {
    double c = std::clamp(value, info.min, info.max);
    cli::warn(fmt::format("{} = {} is far outside the data ({:.4g} .. {:.4g} {}); clamped to {:.4g}",
                          info.name, value, info.min, info.max, info.unit, c));
    return c;
  }
  cli::warn(fmt::format("{} = {} is far outside the data ({:.4g} .. {:.4g} {}): the result is an "
                        "extrapolation (use --clamp to stay inside the data)",
                        info.name, value, info.min, info.max, info.unit));
  return value;
}

// Quantised storage for a model about to be written (`build --quantise`, `quantise`): the
// decoded bodies of `samples` random coefficient vectors through the quantised bases are
// compared with `model`'s. 8 bits first; when bodies move by more than max_error_mm, the columns
// that matter most get 16 bits (mixed_column_bits, halving the 8-bit share until the check
// passes, 4 tries), then all 16 bits, then float32. Records the passing check in
// model.metadata["quantisation_check"]; returns the storage to write with.
// bits 0: per-column widths by each column's effect on decoded bodies (allocate_basis_bits), the
// smallest file within max_error_mm, or with max_mb > 0 the lowest error within max_mb; when no
// allocation passes: all 16 bits, then float32, with a warning (with a budget: InputError).
inline ModelFileOptions choose_allocated_storage(BodyModel& model, int block_rows, int samples, double max_error_mm,
                                                 double max_mb, int min_bits) {
  BitAllocationOptions ao;
  ao.max_error_mm = max_error_mm;
  ao.max_bytes = max_mb * 1e6;
  ao.block_rows = block_rows;
  ao.samples = samples;
  ao.min_bits = min_bits;
  model.metadata.erase("quantisation_check");
  const BitAllocation a = allocate_basis_bits(model, ao, [](const std::string& line) { cli::info(line); });
  if (a.passed) {
    const auto n16 = (a.storage.shape_column_bits.array() == 16).count(),
               f16 = (a.storage.full_column_bits.array() == 16).count();
    model.metadata["quantisation_check"] = {
        {"bits", "per column"},          {"block_rows", block_rows},
        {"shape_16_bit_columns", n16},   {"full_16_bit_columns", f16},
        {"samples", a.check.samples},    {"max_vertex_distance_mm", a.check.max_mm},
        {"mean_vertex_distance_mm", a.check.mean_mm}, {"bound_mm", max_error_mm},
        {"estimated_file_mb", a.file_bytes / 1e6}, {"held_out_max_vertex_distance_mm", a.held_out.max_mm}};
    if (max_mb > 0) model.metadata["quantisation_check"]["budget_mb"] = max_mb;
    cli::info(fmt::format("chosen: {:.2f} MB, {}; confirmed on {} other random bodies: max {:.4f} mm, "
                          "mean {:.5f} mm",
                          a.file_bytes / 1e6, a.check.report(), a.held_out.samples, a.held_out.max_mm,
                          a.held_out.mean_mm));
    return a.storage;
  }
  if (max_mb > 0)
    throw InputError(fmt::format("no per-column allocation within {} MB keeps decoded bodies within {} mm (best: "
                                 "{:.3f} mm at {:.2f} MB): raise --max-mb or --max-error-mm",
                                 max_mb, max_error_mm, a.check.max_mm, a.file_bytes / 1e6));
  cli::warn(fmt::format("no per-column allocation passed the {} mm check in {} checks: trying 16 bits", max_error_mm,
                        a.checks));
  return {};
}

inline ModelFileOptions choose_basis_storage(BodyModel& model, int bits, int block_rows, int samples,
                                             double max_error_mm, double max_mb = 0, int min_bits = kMinBasisBits) {
  if (bits == 0) {
    if (!(max_error_mm > 0)) throw InputError(fmt::format("--max-error-mm must be > 0, got {}", max_error_mm));
    ModelFileOptions o = choose_allocated_storage(model, block_rows, samples, max_error_mm, max_mb, min_bits);
    if (o.basis_bits != 32 || o.shape_column_bits.size() > 0) return o;
    bits = 16;  // the allocation failed: the uniform fallbacks below
  }
  ModelFileOptions o;
  o.basis_bits = bits;
  o.block_rows = block_rows;
  o.validate();
  if (!(max_error_mm > 0)) throw InputError(fmt::format("--max-error-mm must be > 0, got {}", max_error_mm));
  model.metadata.erase("quantisation_check");
  const bool shared = model.full.pca.basis.cols() == model.shape.pca.basis.cols() &&
                      model.full.pca.basis == model.shape.pca.basis;
  Eigen::VectorXd shape_spread = coefficient_spread(model.shape), full_spread = coefficient_spread(model.full);
  if (shared) shape_spread = shape_spread.cwiseMax(full_spread);
  double fraction = 1, error = 0;
  for (int attempt = 0; o.basis_bits < 32; ++attempt) {
    if (o.basis_bits == 8 && attempt > 0) {  // promote the columns that matter most
      fraction = std::min(fraction, 0.7 * max_error_mm / error) / (attempt > 1 ? 2 : 1);
      o.shape_column_bits = mixed_column_bits(model.shape.pca.basis, shape_spread, o.block_rows, fraction);
      o.full_column_bits = shared ? o.shape_column_bits
                                  : mixed_column_bits(model.full.pca.basis, full_spread, o.block_rows, fraction);
    }
    const QuantisationError e = decoded_body_difference(model, with_quantised_bases(model, o), samples);
    const auto n16 = (o.shape_column_bits.array() == 16).count(), f16 = (o.full_column_bits.array() == 16).count();
    const std::string what = o.basis_bits == 16 ? "16-bit bases"
                             : n16 + f16 == 0  ? "8-bit bases"
                                               : fmt::format("8-bit bases with 16 bits for {} of {} shape and {} of {} "
                                                             "full-model columns",
                                                             n16, model.shape.component_count(), f16,
                                                             model.full.component_count());
    cli::info(fmt::format("{}, blocks of {} rows: {}", what, o.block_rows, e.report()));
    if (e.max_mm <= max_error_mm) {
      model.metadata["quantisation_check"] = {{"bits", o.basis_bits},       {"block_rows", o.block_rows},
                                              {"shape_16_bit_columns", n16}, {"full_16_bit_columns", f16},
                                              {"samples", e.samples},       {"max_vertex_distance_mm", e.max_mm},
                                              {"mean_vertex_distance_mm", e.mean_mm},
                                              {"bound_mm", max_error_mm}};
      return o;
    }
    error = e.max_mm;
    if (o.basis_bits == 8 && attempt < 4) continue;
    cli::warn(fmt::format("{} move a decoded body by {:.3f} mm, more than {} mm: {}", what, e.max_mm, max_error_mm,
                          o.basis_bits == 8 ? "trying 16 bits" : "writing float32"));
    o.basis_bits *= 2;
    o.shape_column_bits.resize(0);
    o.full_column_bits.resize(0);
  }
  return o;
}

// parts: whether the verb uses a part-wise model (`build --parts`); the others refuse such a file.
inline BodyModel load_model_for_cli(const std::string& path, PartModelUse parts = PartModelUse::refuse) {
  cli::info("loading model " + path);
  return load_model(path, parts);
}

}  // namespace bodymodel::model_cli
