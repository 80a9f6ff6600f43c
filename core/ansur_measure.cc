#include "core/ansur_measure.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "core/error.h"
#include "core/geometry.h"
#include "core/landmarks.h"
#include "core/measure.h"

namespace bodymodel {

namespace {

// Column order of measure(); docs/measurements.md defines each.
enum Column {
  kStature, kWeight, kChest, kWaist, kButtock, kThigh, kCalf, kBiceps, kForearm, kNeckBase, kShoulder,
  kBiacromial, kHipBreadth, kChestDepth, kWaistDepth, kAcromialHeight, kAxillaHeight, kCrotchHeight,
  kIliocristaleHeight, kKneeHeight, kSpan, kSleeveOutseam, kShoulderElbow, kColumnCount
};

// The girths' planes (plane_of below).
enum PlaneKind { kChestPlane, kWaistPlane, kButtockPlane, kThighPlane, kCalfPlane, kBicepsPlane, kForearmPlane,
                 kShoulderPlane, kPlaneCount };

// Which loops of a section a girth takes: the one whose centroid is nearest the plane's anchor
// (limbs); every loop (the shoulder girth goes round torso and arms); every chain of the torso's
// triangles (arms left out, so a plane above the armpits still measures the torso: the tape runs
// under the arms, the hull bridges the gap).
enum SectionMode { kNearestLoop, kAllLoops, kTorsoChains };

constexpr double kDensityKgPerMm3 = 1.01e-6;  // 1.01 kg/L, as measure_body (core/measure.h)
constexpr int kTubeRings = 8;                 // vertex rings round the reference loop kept per girth

// The skeleton joints the measurements use (bone heads of the MakeHuman default skeleton).
struct Joints {
  Eigen::Vector3d shoulder_r, elbow_r, wrist_r, hip_r, hip_l, knee_r, ankle_r;
};

Joints joints_of(const Skeleton& s) {
  auto head = [&](const char* name) { return Eigen::Vector3d(s.heads.row(s.index(name)).transpose()); };
  return {head("upperarm01.R"), head("lowerarm01.R"), head("wrist.R"),  head("upperleg01.R"),
          head("upperleg01.L"), head("lowerleg01.R"), head("foot.R")};
}

Eigen::Vector3d point(const Eigen::MatrixX3d& V, int v) { return V.row(v).transpose(); }
Eigen::Vector3d mean_point(const Eigen::MatrixX3d& V, const std::vector<int>& vs) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int v : vs) p += point(V, v);
  return p / static_cast<double>(vs.size());
}

// The body's axes: up = +y; left = the horizontal direction from the right to the left hip joint;
// forward = left × up (+z on a template-aligned body).
struct Frame {
  Eigen::Vector3d up = Eigen::Vector3d::UnitY(), left, forward;
};
Frame frame_of(const Joints& j) {
  Frame f;
  Eigen::Vector3d l = j.hip_l - j.hip_r;
  l.y() = 0;
  f.left = l.norm() > 0 ? l.normalized() : Eigen::Vector3d::UnitX();
  f.forward = f.left.cross(f.up);
  return f;
}

// A section plane: points x with (x − origin)·normal = 0, in-plane axes (u, w), and the point
// whose loop is the girth's (the loop whose centroid is nearest to it in the plane).
struct Plane {
  Eigen::Vector3d origin, normal, u, w, anchor;
};

Plane limb_plane(const Eigen::Vector3d& origin, const Eigen::Vector3d& proximal, const Eigen::Vector3d& distal,
                 const Frame& fr) {
  Plane p;
  p.origin = origin;
  p.normal = (distal - proximal).normalized();
  Eigen::Vector3d u = p.normal.cross(fr.forward);
  if (u.norm() < 1e-6) u = p.normal.cross(fr.up);
  p.u = u.normalized();
  p.w = p.normal.cross(p.u);
  p.anchor = proximal + (origin - proximal).dot(p.normal) * p.normal;  // on the limb's axis
  return p;
}

Plane plane_of(int kind, const Eigen::MatrixX3d& V, const Joints& j, const Frame& fr) {
  const AnsurLandmarks& L = ansur_landmarks();
  auto horizontal = [&](const Eigen::Vector3d& origin) {
    return Plane{origin, fr.up, fr.left, fr.forward, 0.5 * (j.hip_l + j.hip_r)};
  };
  switch (kind) {
    case kChestPlane: return horizontal(0.5 * (point(V, L.nipple_r) + point(V, L.nipple_l)));
    case kWaistPlane: return horizontal(point(V, L.omphalion));
    case kButtockPlane: return horizontal(0.5 * (point(V, L.buttock_r) + point(V, L.buttock_l)));
    case kShoulderPlane:
      // Halfway between the acromia and the armpits: the level of the deltoids' bulge.
      return horizontal(0.25 * (point(V, L.acromion_r) + point(V, L.acromion_l) + point(V, L.axilla_r) +
                                point(V, L.axilla_l)));
    case kThighPlane: return limb_plane(point(V, L.gluteal_furrow), j.hip_r, j.knee_r, fr);
    case kCalfPlane: return limb_plane(point(V, L.calf), j.knee_r, j.ankle_r, fr);
    case kBicepsPlane:
      return limb_plane(0.5 * (point(V, L.acromion_r) + point(V, L.olecranon)), j.shoulder_r, j.elbow_r, fr);
    default:  // kForearmPlane: a quarter of the way from elbow to wrist, where the forearm is widest
      return limb_plane(j.elbow_r + 0.25 * (j.wrist_r - j.elbow_r), j.elbow_r, j.wrist_r, fr);
  }
}

// The mesh's triangles and edges, as AnsurMeasurer keeps them.
struct Topology {
  const Eigen::MatrixX3i& F;
  const std::vector<std::array<int, 3>>& face_edges;  // edge ids of each triangle's edges k→k+1
  const std::vector<std::array<int, 2>>& edge_faces;  // the (up to two) triangles of each edge
  const std::vector<std::array<int, 2>>& edge_vertices;
};

struct Loop {
  bool closed = true;      // false: a chain cut short
  bool left_tube = false;  // cut short where the tube ends inside the allowed region
  std::vector<Eigen::Vector2d> points;
  std::vector<int> faces;  // the triangles it crosses (filled only when asked)
};

double cross2(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

// Perimeter of the convex hull (Andrew's monotone chain).
double hull_perimeter(std::vector<Eigen::Vector2d> p) {
  if (p.size() < 2) return 0;
  std::sort(p.begin(), p.end(), [](const auto& a, const auto& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
  std::vector<Eigen::Vector2d> h(2 * p.size());
  size_t k = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross2(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (size_t i = p.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross2(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  double per = 0;
  for (size_t i = 0; i + 1 < k; ++i) per += (h[i + 1] - h[i]).norm();
  return per;
}

const std::vector<std::string> kNames = {
    "stature", "weightkg", "chestcircumference", "waistcircumference", "buttockcircumference",
    "thighcircumference", "calfcircumference", "bicepscircumferenceflexed", "forearmcircumferenceflexed",
    "neckcircumferencebase", "shouldercircumference", "biacromialbreadth", "hipbreadth", "chestdepth",
    "waistdepth", "acromialheight", "axillaheight", "crotchheight", "iliocristaleheight",
    "kneeheightmidpatella", "span", "sleeveoutseam", "shoulderelbowlength"};

}  // namespace

// The loops of the plane's section through the triangles `faces` (membership `in`), tracing
// triangle to triangle across their crossed edges. d: signed distances of the triangles'
// vertices. A chain that leaves the triangle set is returned open, in pieces traced one way;
// `left_tube` unless it ends where `region` (when given: the triangles allowed at all) ends.
static void trace_loops(const Eigen::MatrixX3d& V, const Topology& t, const std::vector<int>& faces,
                        const std::vector<char>& in, const std::vector<char>* region, const std::vector<double>& d,
                        const Plane& plane, bool keep_faces, std::vector<Loop>& loops) {
  const auto& face_edges = t.face_edges;
  const auto& edge_faces = t.edge_faces;
  const auto& edge_vertices = t.edge_vertices;
  std::vector<char> visited(t.F.rows(), 0);
  auto crossed = [&](int e) {
    return (d[edge_vertices[e][0]] >= 0) != (d[edge_vertices[e][1]] >= 0);
  };
  auto edge_point = [&](int e) {
    const int a = edge_vertices[e][0], b = edge_vertices[e][1];
    const double s = d[a] / (d[a] - d[b]);
    const Eigen::Vector3d p = point(V, a) + s * (point(V, b) - point(V, a)) - plane.origin;
    return Eigen::Vector2d(p.dot(plane.u), p.dot(plane.w));
  };
  auto across = [&](int e, int f) { return edge_faces[e][0] == f ? edge_faces[e][1] : edge_faces[e][0]; };
  // A chain stopping before `next`: did it run out of the tube rather than the region?
  auto tube_end = [&](int next) { return next < 0 || (!in[next] && !(region && !(*region)[next])); };
  for (int start : faces) {
    if (visited[start]) continue;
    int first = -1;
    for (int e : face_edges[start])
      if (crossed(e)) { first = e; break; }
    if (first < 0) continue;
    Loop loop;
    loop.points.push_back(edge_point(first));
    const int behind = across(first, start);
    if (behind < 0 || (!visited[behind] && tube_end(behind))) loop.left_tube = true;
    int cur = start, enter = first;
    while (true) {
      visited[cur] = 1;
      if (keep_faces) loop.faces.push_back(cur);
      int exit = -1;
      for (int e : face_edges[cur])
        if (e != enter && crossed(e)) { exit = e; break; }
      const int next = exit < 0 ? -1 : across(exit, cur);
      if (next == start) break;
      if (exit >= 0) loop.points.push_back(edge_point(exit));
      if (next < 0 || !in[next] || visited[next]) {
        loop.closed = false;
        if (!(next >= 0 && visited[next]) && tube_end(next)) loop.left_tube = true;
        break;
      }
      enter = exit;
      cur = next;
    }
    if (loop.points.size() >= 3 || !loop.closed) loops.push_back(std::move(loop));
  }
}

// The loops a girth takes (SectionMode). Empty when the tube was too narrow for them.
static std::vector<const Loop*> chosen_loops(const std::vector<Loop>& loops, const Plane& plane, int mode) {
  std::vector<const Loop*> out;
  if (mode != kNearestLoop) {
    for (const Loop& l : loops) {
      if (l.left_tube || (mode == kAllLoops && !l.closed)) return {};
      out.push_back(&l);
    }
    return out;
  }
  const Eigen::Vector3d a3 = plane.anchor - plane.origin;
  const Eigen::Vector2d a(a3.dot(plane.u), a3.dot(plane.w));
  double best = std::numeric_limits<double>::infinity();
  const Loop* pick = nullptr;
  for (const Loop& l : loops) {
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    for (const auto& p : l.points) c += p;
    c /= static_cast<double>(l.points.size());
    if ((c - a).norm() < best) { best = (c - a).norm(); pick = &l; }
  }
  if (pick && pick->closed) out.push_back(pick);
  return out;
}

AnsurMeasurer::AnsurMeasurer(const Eigen::MatrixX3i& F, const SkinWeights& W, const Eigen::MatrixX3d& reference_V,
                             const Skeleton& reference_skeleton)
    : F_(F) {
  const int n = kSurveyTemplateVertexCount;
  if (reference_V.rows() != n || W.rows() != n)
    throw InputError("AnsurMeasurer: the reference body and the weights need the template's " + std::to_string(n) +
                     " vertices (got " + std::to_string(reference_V.rows()) + " and " + std::to_string(W.rows()) + ")");
  if (W.cols() != reference_skeleton.bone_count())
    throw InputError("AnsurMeasurer: the weights have " + std::to_string(W.cols()) + " bones, the skeleton " +
                     std::to_string(reference_skeleton.bone_count()));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (F(f, k) < 0 || F(f, k) >= n)
        throw InputError("AnsurMeasurer: triangle " + std::to_string(f) + " has vertex " + std::to_string(F(f, k)));
  bone_names_ = reference_skeleton.names;
  // Edges and their triangles.
  std::map<std::pair<int, int>, int> edge_id;
  face_edges_.resize(F.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = std::min(F(f, k), F(f, (k + 1) % 3)), b = std::max(F(f, k), F(f, (k + 1) % 3));
      auto [it, fresh] = edge_id.emplace(std::make_pair(a, b), static_cast<int>(edge_vertices_.size()));
      if (fresh) {
        edge_vertices_.push_back({a, b});
        edge_faces_.push_back({-1, -1});
      }
      auto& ef = edge_faces_[it->second];
      (ef[0] < 0 ? ef[0] : ef[1]) = static_cast<int>(f);
      face_edges_[f][k] = it->second;
    }
  // The torso region: triangles with no vertex mostly skinned to an arm or hand bone.
  std::vector<char> arm_bone(bone_names_.size(), 0);
  for (size_t b = 0; b < bone_names_.size(); ++b)
    for (const char* prefix : {"upperarm", "lowerarm", "wrist", "finger", "metacarpal"})
      if (bone_names_[b].rfind(prefix, 0) == 0) arm_bone[b] = 1;
  std::vector<double> arm_weight(n, 0.0);
  for (int v = 0; v < n; ++v)
    for (SkinWeights::InnerIterator it(W, v); it; ++it)
      if (arm_bone[it.col()]) arm_weight[v] += it.value();
  torso_.assign(F.rows(), 1);
  everywhere_.assign(F.rows(), 1);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    all_faces_.push_back(static_cast<int>(f));
    for (int k = 0; k < 3; ++k)
      if (arm_weight[F(f, k)] > 0.5) torso_[f] = 0;
    if (torso_[f]) torso_faces_.push_back(static_cast<int>(f));
  }
  build_tubes(reference_V, reference_skeleton);
  // Skinning rows of the vertices the posed measurements use.
  const AnsurLandmarks& L = ansur_landmarks();
  posed_vertices_ = {L.fingertip_r, L.fingertip_l, L.acromion_r, L.lateral_deltoid, L.radiale, L.stylion};
  for (int v : posed_vertices_) {
    std::vector<std::pair<int, double>> row;
    for (SkinWeights::InnerIterator it(W, v); it; ++it) row.emplace_back(static_cast<int>(it.col()), it.value());
    posed_weights_.push_back(std::move(row));
  }
}

void AnsurMeasurer::build_tubes(const Eigen::MatrixX3d& V, const Skeleton& skeleton) {
  const Joints j = joints_of(skeleton);
  const Frame fr = frame_of(j);
  const Topology topo{F_, face_edges_, edge_faces_, edge_vertices_};
  std::vector<std::vector<int>> faces_of_vertex(V.rows());
  for (Eigen::Index f = 0; f < F_.rows(); ++f)
    for (int k = 0; k < 3; ++k) faces_of_vertex[F_(f, k)].push_back(static_cast<int>(f));
  for (int kind = 0; kind < kPlaneCount; ++kind) {
    Section s;
    s.plane = kind;
    s.mode = kind == kShoulderPlane ? kAllLoops
             : (kind == kChestPlane || kind == kWaistPlane || kind == kButtockPlane) ? kTorsoChains
                                                                                     : kNearestLoop;
    const std::vector<char>* region = s.mode == kTorsoChains ? &torso_ : nullptr;
    const Plane p = plane_of(kind, V, j, fr);
    std::vector<double> d(V.rows());
    for (Eigen::Index v = 0; v < V.rows(); ++v) d[v] = (point(V, static_cast<int>(v)) - p.origin).dot(p.normal);
    std::vector<Loop> loops;
    trace_loops(V, topo, region ? torso_faces_ : all_faces_, region ? torso_ : everywhere_, region, d, p, true, loops);
    const auto chosen = chosen_loops(loops, p, s.mode);
    if (chosen.empty())
      throw InputError("AnsurMeasurer: the reference body has no section for girth " + std::to_string(kind));
    // The tube: the loops' triangles grown by kTubeRings rings of vertex neighbours (torso girths:
    // within the torso).
    s.in_tube.assign(F_.rows(), 0);
    for (const Loop* l : chosen)
      for (int f : l->faces) s.in_tube[f] = 1;
    for (int ring = 0; ring < kTubeRings; ++ring) {
      std::vector<char> grown = s.in_tube;
      for (Eigen::Index f = 0; f < F_.rows(); ++f)
        if (s.in_tube[f])
          for (int k = 0; k < 3; ++k)
            for (int g : faces_of_vertex[F_(f, k)]) grown[g] = 1;
      s.in_tube.swap(grown);
    }
    std::vector<char> used(V.rows(), 0);
    for (Eigen::Index f = 0; f < F_.rows(); ++f) {
      if (region && !(*region)[f]) s.in_tube[f] = 0;
      if (s.in_tube[f]) {
        s.faces.push_back(static_cast<int>(f));
        for (int k = 0; k < 3; ++k) used[F_(f, k)] = 1;
      }
    }
    for (Eigen::Index v = 0; v < V.rows(); ++v)
      if (used[v]) s.vertices.push_back(static_cast<int>(v));
    sections_.push_back(std::move(s));
  }
}

const std::vector<std::string>& AnsurMeasurer::names() { return kNames; }

const std::vector<std::string>& AnsurMeasurer::units() {
  static const std::vector<std::string> u = [] {
    std::vector<std::string> out(kColumnCount, "mm");
    out[kWeight] = "kg";
    return out;
  }();
  return u;
}

const std::vector<std::string>& AnsurMeasurer::definitions() {
  static const std::vector<std::string> d = {
      "floor (lowest vertex) to the top of the head",
      "enclosed volume x 1.01 kg/L (the CSV stores tenths of a kg)",
      "horizontal girth at the nipples / bust points (convex hull)",
      "horizontal girth at the omphalion (navel)",
      "horizontal girth at the buttocks' maximum protrusion (template level)",
      "right thigh girth square to the thigh at the gluteal furrow",
      "right calf girth square to the shank at the calf's maximum (template level)",
      "right upper-arm girth mid acromion-olecranon, square to the arm (relaxed arm: approximation)",
      "right forearm girth a quarter of the way elbow to wrist, square to the forearm (relaxed)",
      "length of the template's edge loop round the neck base by the cervicale and the jugular notch",
      "horizontal girth round shoulders and arms halfway between acromia and armpits",
      "acromion to acromion, straight",
      "breadth of the torso section at the buttocks' level",
      "front-to-back depth of the torso section at the chest girth's level",
      "front-to-back depth of the torso section at the omphalion",
      "floor to the right acromion",
      "floor to the right armpit",
      "floor to the crotch",
      "floor to the right iliac crest",
      "floor to the middle of the right kneecap",
      "middle fingertip to middle fingertip, arms posed straight and horizontal",
      "right acromion over the deltoid and the lateral elbow to the wrist (stylion), arm posed straight",
      "acromion to the underside of the elbow flexed 90 degrees, upper arm hanging (modelled)"};
  return d;
}

// Girth and extents of one section on V (d: scratch of V.rows(), overwritten on the tube).
AnsurMeasurer::SectionValues AnsurMeasurer::cut(const Section& s, const Eigen::MatrixX3d& V, const Eigen::Vector3d& origin,
                                                const Eigen::Vector3d& normal, const Eigen::Vector3d& u,
                                                const Eigen::Vector3d& w, const Eigen::Vector3d& anchor,
                                                std::vector<double>& d) const {
  const Plane p{origin, normal, u, w, anchor};
  const Topology topo{F_, face_edges_, edge_faces_, edge_vertices_};
  const std::vector<char>* region = s.mode == kTorsoChains ? &torso_ : nullptr;
  for (int v : s.vertices) d[v] = (point(V, v) - p.origin).dot(p.normal);
  std::vector<Loop> loops;
  trace_loops(V, topo, s.faces, s.in_tube, region, d, p, false, loops);
  std::vector<const Loop*> chosen = chosen_loops(loops, p, s.mode);
  if (chosen.empty()) {
    // The loop left its tube (a body far from the reference): cut the whole mesh.
    ++*fallbacks_;
    for (Eigen::Index v = 0; v < V.rows(); ++v) d[v] = (point(V, static_cast<int>(v)) - p.origin).dot(p.normal);
    loops.clear();
    trace_loops(V, topo, region ? torso_faces_ : all_faces_, region ? torso_ : everywhere_, region, d, p, false, loops);
    chosen = chosen_loops(loops, p, s.mode);
  }
  std::vector<Eigen::Vector2d> pts;
  for (const Loop* l : chosen) pts.insert(pts.end(), l->points.begin(), l->points.end());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (pts.empty()) return {nan, nan, nan};
  Eigen::Vector2d lo = pts[0], hi = pts[0];
  for (const auto& q : pts) lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
  SectionValues r;
  r.extent_u = hi.x() - lo.x();
  r.extent_w = hi.y() - lo.y();
  r.girth = hull_perimeter(std::move(pts));
  return r;
}

Pose AnsurMeasurer::outstretched_arms_pose(const Eigen::MatrixX3d& V, const Skeleton& s) const {
  const AnsurLandmarks& L = ansur_landmarks();
  const Frame fr = frame_of(joints_of(s));
  Pose pose = Pose::rest(s.bone_count());
  for (int side = 0; side < 2; ++side) {
    const std::string sfx = side == 0 ? ".R" : ".L";
    const Eigen::Vector3d out = side == 0 ? Eigen::Vector3d(-fr.left) : fr.left;
    const int bones[3] = {s.index("upperarm01" + sfx), s.index("lowerarm01" + sfx), s.index("wrist" + sfx)};
    // Each segment (shoulder→elbow, elbow→wrist, wrist→fingertip) turned to point straight out.
    const Eigen::Vector3d ends[4] = {s.heads.row(bones[0]).transpose(), s.heads.row(bones[1]).transpose(),
                                     s.heads.row(bones[2]).transpose(),
                                     point(V, side == 0 ? L.fingertip_r : L.fingertip_l)};
    for (int k = 0; k < 3; ++k) {
      const Eigen::Matrix3d want = Eigen::Quaterniond::FromTwoVectors(ends[k + 1] - ends[k], out).toRotationMatrix();
      const int parent = s.parents[bones[k]];
      const Eigen::Matrix3d q_parent = parent < 0 ? Eigen::Matrix3d::Identity() : world_rotations(s, pose)[parent];
      pose.rotations[bones[k]] = q_parent.transpose() * want;
    }
  }
  return pose;
}

Eigen::VectorXd AnsurMeasurer::measure(const Eigen::MatrixX3d& V, const Skeleton& skeleton) const {
  if (V.rows() != kSurveyTemplateVertexCount)
    throw InputError("ANSUR measurements need a body with the hm08 template's topology (" +
                     std::to_string(kSurveyTemplateVertexCount) + " vertices), got " + std::to_string(V.rows()));
  if (!V.allFinite()) throw InputError("ANSUR measurements: the vertices contain NaN or infinite values");
  if (skeleton.names != bone_names_)
    throw InputError("ANSUR measurements: the skeleton's bones differ from the reference skeleton's");
  const AnsurLandmarks& L = ansur_landmarks();
  const Joints j = joints_of(skeleton);
  const Frame fr = frame_of(j);
  Eigen::VectorXd m(kColumnCount);
  const double floor = V.col(1).minCoeff();
  auto height = [&](const Eigen::Vector3d& p) { return p.y() - floor; };
  m(kStature) = V.col(1).maxCoeff() - floor;
  m(kWeight) = signed_volume(V, F_) * kDensityKgPerMm3;

  std::vector<double> d(V.rows(), 0.0);
  SectionValues r[kPlaneCount];
  for (const Section& s : sections_) {
    const Plane p = plane_of(s.plane, V, j, fr);
    r[s.plane] = cut(s, V, p.origin, p.normal, p.u, p.w, p.anchor, d);
  }
  m(kChest) = r[kChestPlane].girth;
  m(kWaist) = r[kWaistPlane].girth;
  m(kButtock) = r[kButtockPlane].girth;
  m(kThigh) = r[kThighPlane].girth;
  m(kCalf) = r[kCalfPlane].girth;
  m(kBiceps) = r[kBicepsPlane].girth;
  m(kForearm) = r[kForearmPlane].girth;
  m(kShoulder) = r[kShoulderPlane].girth;
  m(kHipBreadth) = r[kButtockPlane].extent_u;
  m(kChestDepth) = r[kChestPlane].extent_w;
  m(kWaistDepth) = r[kWaistPlane].extent_w;
  double ring = 0;
  for (size_t k = 0; k < L.neck_base_ring.size(); ++k)
    ring += (point(V, L.neck_base_ring[k]) - point(V, L.neck_base_ring[(k + 1) % L.neck_base_ring.size()])).norm();
  m(kNeckBase) = ring;

  const Eigen::Vector3d acromion = point(V, L.acromion_r);
  m(kBiacromial) = (point(V, L.acromion_l) - acromion).norm();
  m(kAcromialHeight) = height(acromion);
  m(kAxillaHeight) = height(point(V, L.axilla_r));
  m(kCrotchHeight) = height(point(V, L.crotch));
  m(kIliocristaleHeight) = height(mean_point(V, L.iliac_crest));
  m(kKneeHeight) = height(0.5 * (point(V, L.knee_front) + point(V, L.patella_top)));
  // The survey's arm hangs straight down with the elbow flexed 90°: the acromion's height above
  // the shoulder joint (on the shoulder blade, it does not move with the arm), the upper arm's
  // length, and the olecranon, which turns about the elbow joint to lie below it at its distance.
  m(kShoulderElbow) = (acromion - j.shoulder_r).dot(fr.up) + (j.elbow_r - j.shoulder_r).norm() +
                      (point(V, L.olecranon) - j.elbow_r).norm();

  // Span and sleeve outseam on the arms posed straight out: skin only the landmark vertices.
  const BoneTransforms M = forward_kinematics(skeleton, outstretched_arms_pose(V, skeleton));
  std::vector<Eigen::Vector3d> posed(posed_vertices_.size(), Eigen::Vector3d::Zero());
  for (size_t k = 0; k < posed_vertices_.size(); ++k)
    for (const auto& [bone, w] : posed_weights_[k]) posed[k] += w * (M[bone] * point(V, posed_vertices_[k]));
  m(kSpan) = (posed[1] - posed[0]).norm();
  m(kSleeveOutseam) = (posed[3] - posed[2]).norm() + (posed[4] - posed[3]).norm() + (posed[5] - posed[4]).norm();
  return m;
}

}  // namespace bodymodel
