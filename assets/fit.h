// Fitting MakeHuman assets to any hm08 body by their binding (assets/binding.h), and carrying
// the body's skinning weights (or any per-vertex attribute) to the asset through the same rows.
//
// Bodies here are ALL hm08 vertices (19158 rows, helpers included: garments are bound to the
// helper-tights and helper-skirt shells, hair to helper-hair), in millimetres, as
// MakeHuman::build_vertices returns them. The binding's offsets are in decimetres; the scale
// lines turn them into body units (|Δbody| in mm over a denominator in dm), so a body in mm
// gives the asset in mm. A binding without scale lines is scaled by 100 (dm → mm).
#pragma once

#include <Eigen/Core>
#include <Eigen/Sparse>
#include <filesystem>
#include <optional>
#include <vector>

#include "assets/binding.h"
#include "core/io/mesh_io.h"
#include "core/skeleton.h"

namespace bodymodel {

// The diagonal S of the offset transform on this body (mm per file unit, per axis).
// Throws InputError if the body has too few rows for the binding.
Eigen::Vector3d asset_offset_scale(const AssetBinding& binding, const Eigen::MatrixX3d& body_mm);

// The asset's vertices on this body: x_i = Σ_k w_ik · body[v_ik] + S · d_i (#A by 3, mm).
// MakeHuman fits assets to the REST body and skins them (proxy.py getCoords); fit to a rest body
// and pose with asset_skin_weights, since the offsets do not rotate with the limbs.
Eigen::MatrixX3d fit_asset(const AssetBinding& binding, const Eigen::MatrixX3d& body_mm);

// Skinning weights of the asset (#A by #bones) from the body's (#body vertices by #bones):
// row i = Σ_k w_ik · body_weights[v_ik], negative products dropped (a few rows extrapolate
// with a negative barycentric weight), entries below 1e-4 dropped as MakeHuman does, rows
// renormalised to sum 1. A row with no weight left takes its largest-weight vertex's row.
SkinWeights asset_skin_weights(const AssetBinding& binding, const SkinWeights& body_weights);

// Any dense per-vertex attribute (#body vertices by k, e.g. colours or per-vertex rig
// coefficients) carried the same way, without dropping or renormalising: Σ_k w_ik · M[v_ik].
Eigen::MatrixXd carry_through_binding(const AssetBinding& binding, const Eigen::MatrixXd& per_body_vertex);

// The body vertices the assets hide (1 = hidden), for a body of `vertex_count` vertices.
std::vector<char> hidden_body_vertices(const std::vector<const AssetBinding*>& assets, int vertex_count);
// The faces of F left visible: a face with any hidden vertex is hidden (so the skin under a
// garment does not show through at the garment's edges).
Eigen::MatrixX3i visible_faces(const Eigen::MatrixX3i& F, const std::vector<char>& hidden);

// An asset as read from disk: its binding, its OBJ (decimetres, as modelled) and its material.
struct Asset {
  std::filesystem::path file;      // the .mhclo / .proxy
  AssetBinding binding;
  ObjContents obj;                 // V #A by 3 (dm), polygons of the asset
  Eigen::MatrixX3i faces;          // the polygons triangulated (fans)
  std::optional<AssetMaterial> material;  // when the binding names a material file
};

// Reads a binding, its obj_file and material from the binding's folder. InputError if the OBJ
// is missing or its vertex count differs from the binding's rows.
Asset load_asset(const std::filesystem::path& binding_file);

// Every .mhclo and .proxy file under `folder` (recursively), sorted by path.
std::vector<std::filesystem::path> find_asset_files(const std::filesystem::path& folder);

}  // namespace bodymodel
