// Scan-like input from any mesh (`bodymodel scanify`): the synthetic database's scanner
// simulation (simulate_scan: four pillars, holes where no pillar sees the surface, Gaussian
// noise, normals estimated from the noisy points) run on a given mesh, e.g. a FAUST or SCAPE
// registration, so real bodies can be registered the way scans are.
#pragma once

#include <Eigen/Core>
#include <string>

#include "core/mesh.h"
#include "tools/synth/synthetic_scans.h"

namespace bodymodel {

struct ScanifyOptions {
  ScannerOptions scanner;  // noise_sigma_mm, min_points, pillars, ...
  // true: the pillar scanner's visibility (holes under the arms, between the legs, the top of
  // the head and the soles); false: the whole surface sampled uniformly by area (noise only).
  bool holes = true;
  unsigned seed = 1;
  double mm_per_unit = 1;  // the caller's --scale (already applied to the mesh): for messages only
};

// A scan of `mesh` (millimetres, +y up, the subject standing on the scanner's platform).
// Points uniform by area on the seen surface, Gaussian noise of scanner.noise_sigma_mm per
// coordinate, unit normals from the k nearest noisy points (PCA) oriented towards the pillar
// that saw the point (holes on) or outwards along the surface (holes off).
// Throws InputError naming `what` for an empty or non-finite mesh or one whose size is not a
// body's in millimetres (core/body_size.h: a unit mix-up).
PointCloud scanify_mesh(const Mesh& mesh, const ScanifyOptions& options,
                        const std::string& what = "mesh");

// A seed of its own per mesh name, stable across runs and platforms (FNV-1a of `name` mixed
// with `seed`), so a mesh's scan does not depend on which other meshes are in the run.
unsigned scan_seed(unsigned seed, const std::string& name);

}  // namespace bodymodel
