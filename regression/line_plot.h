// A minimal PNG line chart (no plotting library): stacked panels, one curve each, axes with
// numeric tick labels in a built-in 3×5 pixel font, the minimum marked. Used for the filtered
// model's RMSE against the number of kept components.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

namespace bodymodel {

struct LinePanel {
  std::string title;   // e.g. "height_cm rmse cm" (letters, digits, _ % . - : and spaces)
  Eigen::VectorXd x;   // #points
  Eigen::VectorXd y;   // #points (finite)
  // Optional second curve (orange), its own points; empty = none.
  Eigen::VectorXd x2, y2;
  bool mark_minimum = true;  // red dot on the first curve's minimum
};

struct LinePlotOptions {
  int width = 720;         // pixels
  int panel_height = 170;  // pixels a panel
  std::string x_label = "kept components";
};

// Writes one PNG (atomically) with the panels stacked top to bottom. Throws InputError for an
// empty panel list, mismatched x/y sizes or non-finite values.
void write_line_plot_png(const std::filesystem::path& path, const std::vector<LinePanel>& panels,
                         const LinePlotOptions& options = {});

}  // namespace bodymodel
