// Shape-space files (core/shape_space.h) as JSON: {"format": "bodymodel-shape-space", "version": 1,
// "parameters": [...], "mean": [...], "sd": [...], "basis": [[one row per parameter]],
// "explained", "people", "source"}. Small (a few hundred numbers per component), readable, and
// made by `bodymodel shape-space`.
#pragma once

#include <filesystem>
#include <string>

#include "core/shape_space.h"

namespace bodymodel {

std::string shape_space_json(const ShapeSpace& space);
// InputError naming the file for unreadable JSON, a wrong format tag or inconsistent sizes.
// Parameter names are checked against MakeHuman by ShapeSpace::validate, not here.
ShapeSpace read_shape_space(const std::filesystem::path& path);

}  // namespace bodymodel
