#include "tools/render/render.h"

#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "core/geometry.h"
#include "core/io/atomic_write.h"

namespace bodymodel {

void Image::save_png(const std::filesystem::path& path) const {
  std::string bytes;
  auto sink = [](void* ctx, void* data, int size) {
    static_cast<std::string*>(ctx)->append(static_cast<const char*>(data), size);
  };
  if (!stbi_write_png_to_func(sink, &bytes, width, height, 3, rgb.data(), width * 3))
    throw InputError("cannot encode PNG '" + path.string() + "'");
  write_atomically(path, [&](std::ostream& out) { out.write(bytes.data(), bytes.size()); });
}

void Image::paste(const Image& o, int x0, int y0) {
  for (int y = 0; y < o.height; ++y)
    for (int x = 0; x < o.width; ++x) {
      int X = x0 + x, Y = y0 + y;
      if (X < 0 || Y < 0 || X >= width || Y >= height) continue;
      for (int c = 0; c < 3; ++c) rgb[(size_t(Y) * width + X) * 3 + c] = o.rgb[(size_t(y) * o.width + x) * 3 + c];
    }
}

namespace {

struct View {
  Eigen::Matrix3d R;     // rows: right, up, backward (towards the viewer)
  Eigen::Vector2d center;
  double scale;          // pixels per world unit
  int width, height;
  Eigen::Vector3d to_screen(const Eigen::Vector3d& p) const {
    Eigen::Vector3d q = R * p;
    return {width / 2.0 + (q.x() - center.x()) * scale, height / 2.0 - (q.y() - center.y()) * scale,
            q.z()};
  }
};

View make_view(const Eigen::MatrixX3d& V, int width, int height, const Camera& cam) {
  View v;
  Eigen::Vector3d f = cam.forward.normalized();
  Eigen::Vector3d right = f.cross(cam.up).normalized();
  Eigen::Vector3d up = right.cross(f);
  v.R.row(0) = right.transpose();
  v.R.row(1) = up.transpose();
  v.R.row(2) = -f.transpose();
  v.width = width;
  v.height = height;
  Eigen::MatrixX3d pts;
  if ((cam.frame_min.array() <= cam.frame_max.array()).all()) {
    pts.resize(8, 3);
    for (int i = 0; i < 8; ++i)
      pts.row(i) << (i & 1 ? cam.frame_max : cam.frame_min).x(), (i & 2 ? cam.frame_max : cam.frame_min).y(),
          (i & 4 ? cam.frame_max : cam.frame_min).z();
  } else {
    pts = V;
  }
  Eigen::MatrixX3d Q = pts * v.R.transpose();
  Eigen::Vector3d lo = Q.colwise().minCoeff(), hi = Q.colwise().maxCoeff();
  v.center = 0.5 * (lo + hi).head<2>();
  double sx = (hi.x() - lo.x()) / (width * (1 - 2 * cam.margin));
  double sy = (hi.y() - lo.y()) / (height * (1 - 2 * cam.margin));
  v.scale = 1.0 / std::max({sx, sy, 1e-12});
  return v;
}

Eigen::Vector3d shade(const Eigen::Vector3d& albedo, const Eigen::Vector3d& n_view) {
  // Headlight plus a key light from the upper left; two-sided.
  Eigen::Vector3d key = Eigen::Vector3d(-0.4, 0.6, 1.0).normalized();
  double d = 0.25 + 0.55 * std::abs(n_view.z()) + 0.3 * std::max(0.0, n_view.dot(key));
  return (albedo * std::min(d, 1.1)).cwiseMin(1.0);
}

void rasterize(Image& img, std::vector<float>& zbuf, const View& view, const Eigen::MatrixX3d& V,
               const Eigen::MatrixX3i& F, const Eigen::MatrixX3d& colors) {
  Eigen::MatrixX3d N = vertex_normals(V, F);
  const int nv = static_cast<int>(V.rows());
  std::vector<Eigen::Vector3d> s(nv), c(nv);
  for (int i = 0; i < nv; ++i) {
    s[i] = view.to_screen(V.row(i).transpose());
    Eigen::Vector3d albedo = colors.rows() == nv ? Eigen::Vector3d(colors.row(i).transpose())
                                                 : Eigen::Vector3d(0.78, 0.76, 0.74);
    c[i] = shade(albedo, view.R * N.row(i).transpose());
  }
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const int ia = F(f, 0), ib = F(f, 1), ic = F(f, 2);
    const Eigen::Vector3d &a = s[ia], &b = s[ib], &cc = s[ic];
    double det = (b.x() - a.x()) * (cc.y() - a.y()) - (cc.x() - a.x()) * (b.y() - a.y());
    if (std::abs(det) < 1e-12) continue;
    int x0 = std::max(0, int(std::floor(std::min({a.x(), b.x(), cc.x()}))));
    int x1 = std::min(img.width - 1, int(std::ceil(std::max({a.x(), b.x(), cc.x()}))));
    int y0 = std::max(0, int(std::floor(std::min({a.y(), b.y(), cc.y()}))));
    int y1 = std::min(img.height - 1, int(std::ceil(std::max({a.y(), b.y(), cc.y()}))));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        double px = x + 0.5, py = y + 0.5;
        double l1 = ((px - a.x()) * (cc.y() - a.y()) - (cc.x() - a.x()) * (py - a.y())) / det;
        double l2 = ((b.x() - a.x()) * (py - a.y()) - (px - a.x()) * (b.y() - a.y())) / det;
        double l0 = 1 - l1 - l2;
        if (l0 < 0 || l1 < 0 || l2 < 0) continue;
        float z = float(l0 * a.z() + l1 * b.z() + l2 * cc.z());
        float& zb = zbuf[size_t(y) * img.width + x];
        if (z <= zb) continue;  // larger z is nearer the viewer
        zb = z;
        Eigen::Vector3d col = l0 * c[ia] + l1 * c[ib] + l2 * c[ic];
        for (int k = 0; k < 3; ++k)
          img.rgb[(size_t(y) * img.width + x) * 3 + k] = uint8_t(std::lround(std::clamp(col(k), 0.0, 1.0) * 255));
      }
  }
}

}  // namespace

Image render_mesh(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const Eigen::MatrixX3d& colors,
                  int width, int height, const Camera& camera) {
  Image img(width, height);
  if (V.rows() == 0) return img;
  std::vector<float> zbuf(size_t(width) * height, -std::numeric_limits<float>::infinity());
  rasterize(img, zbuf, make_view(V, width, height, camera), V, F, colors);
  return img;
}

Image render_points(const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& N, int width, int height,
                    const Camera& camera) {
  Image img(width, height);
  if (P.rows() == 0) return img;
  View view = make_view(P, width, height, camera);
  std::vector<float> zbuf(size_t(width) * height, -std::numeric_limits<float>::infinity());
  for (Eigen::Index i = 0; i < P.rows(); ++i) {
    Eigen::Vector3d q = view.to_screen(P.row(i).transpose());
    Eigen::Vector3d col = N.rows() == P.rows()
                              ? shade(Eigen::Vector3d(0.55, 0.65, 0.8), view.R * N.row(i).transpose())
                              : Eigen::Vector3d(0.3, 0.4, 0.6);
    int x = int(q.x()), y = int(q.y());
    for (int dy = 0; dy <= 1; ++dy)
      for (int dx = 0; dx <= 1; ++dx) {
        int X = x + dx, Y = y + dy;
        if (X < 0 || Y < 0 || X >= width || Y >= height) continue;
        float& zb = zbuf[size_t(Y) * width + X];
        if (q.z() <= zb) continue;
        zb = float(q.z());
        for (int k = 0; k < 3; ++k) img.rgb[(size_t(Y) * width + X) * 3 + k] = uint8_t(col(k) * 255);
      }
  }
  return img;
}

Image render_row(const std::vector<Eigen::MatrixX3d>& meshes, const Eigen::MatrixX3i& F,
                 const std::vector<Eigen::MatrixX3d>& colors, int cell_width, int height,
                 const Camera& camera) {
  std::vector<ColouredMesh> cm;
  for (size_t i = 0; i < meshes.size(); ++i) cm.push_back({meshes[i], F, i < colors.size() ? colors[i] : Eigen::MatrixX3d()});
  return render_row(cm, cell_width, height, camera);
}

Image render_row(const std::vector<ColouredMesh>& meshes, int cell_width, int height, const Camera& camera) {
  Image row(cell_width * static_cast<int>(meshes.size()), height);
  if (meshes.empty()) return row;
  // Common frame: the union of all bounding boxes, centred on each mesh horizontally.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (auto& m : meshes) {
    const auto& V = m.V;
    Eigen::Vector3d c = 0.5 * (V.colwise().minCoeff() + V.colwise().maxCoeff()).transpose();
    Eigen::MatrixX3d centred = V.rowwise() - Eigen::RowVector3d(c.x(), 0, c.z());
    lo = lo.cwiseMin(centred.colwise().minCoeff().transpose());
    hi = hi.cwiseMax(centred.colwise().maxCoeff().transpose());
  }
  for (size_t i = 0; i < meshes.size(); ++i) {
    const auto& V = meshes[i].V;
    Eigen::Vector3d c = 0.5 * (V.colwise().minCoeff() + V.colwise().maxCoeff()).transpose();
    Eigen::MatrixX3d centred = V.rowwise() - Eigen::RowVector3d(c.x(), 0, c.z());
    Camera cam = camera;
    cam.frame_min = lo;
    cam.frame_max = hi;
    row.paste(render_mesh(centred, meshes[i].F, meshes[i].colors, cell_width, height, cam),
              static_cast<int>(i) * cell_width, 0);
  }
  return row;
}

Eigen::MatrixX3d heat_colors(const Eigen::VectorXd& values, double vmin, double vmax) {
  static const double stops[5][3] = {{0.19, 0.25, 0.85}, {0.1, 0.75, 0.9}, {0.2, 0.8, 0.3},
                                     {0.98, 0.85, 0.15}, {0.9, 0.15, 0.1}};
  Eigen::MatrixX3d C(values.size(), 3);
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    double t = vmax > vmin ? (values(i) - vmin) / (vmax - vmin) : 0;
    t = std::isfinite(t) ? std::clamp(t, 0.0, 1.0) * 4 : 4;
    int k = std::min(3, int(t));
    double u = t - k;
    for (int c = 0; c < 3; ++c) C(i, c) = (1 - u) * stops[k][c] + u * stops[k + 1][c];
  }
  return C;
}

Image heat_colorbar(int width, int height) {
  Image img(width, height);
  Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(width, 0, 1);
  Eigen::MatrixX3d C = heat_colors(t, 0, 1);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int k = 0; k < 3; ++k) img.rgb[(size_t(y) * width + x) * 3 + k] = uint8_t(C(x, k) * 255);
  return img;
}

}  // namespace bodymodel
