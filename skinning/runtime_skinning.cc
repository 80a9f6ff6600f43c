#include "skinning/runtime_skinning.h"

#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "core/error.h"

namespace bodymodel {
namespace {

constexpr int kBlock = 256;

#if defined(__GNUC__) && defined(__x86_64__)
#define BODYMODEL_CLONES __attribute__((target_clones("arch=haswell", "default")))
#else
#define BODYMODEL_CLONES
#endif

// LBS: per vertex, blend the slots' 3 by 4 matrices (12 contiguous floats each, in L1) and apply
// the blend to the rest position; the 12-wide blend vectorises (SLP) and needs no gathers.
BODYMODEL_CLONES
void lbs_block(int K, int n, int begin, int end, const int* __restrict idx, const float* __restrict w,
               const float* __restrict rest, const float* __restrict bones, float* __restrict ox,
               float* __restrict oy, float* __restrict oz) {
  for (int v = begin; v < end; ++v) {
    float m[12] = {0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f};
    const int* __restrict iv = idx + static_cast<size_t>(v) * K;
    const float* __restrict wv = w + static_cast<size_t>(v) * K;
    for (int k = 0; k < K; ++k) {
      const float* __restrict M = bones + 12 * iv[k];
      const float wk = wv[k];
      for (int e = 0; e < 12; ++e) m[e] += wk * M[e];
    }
    const float x = rest[3 * static_cast<size_t>(v)], y = rest[3 * static_cast<size_t>(v) + 1],
                z = rest[3 * static_cast<size_t>(v) + 2];
    ox[v] = m[0] * x + m[1] * y + m[2] * z + m[3];
    oy[v] = m[4] * x + m[5] * y + m[6] * z + m[7];
    oz[v] = m[8] * x + m[9] * y + m[10] * z + m[11];
  }
}

// AS / MWE: out_j = Σ_k Σ_i c[k][4j+i] · bone[12 b + 4j + i], coefficients vertex-major, 12 per
// slot (AS's p_k repeated for the three rows), so each slot is one 12-wide multiply-add.
BODYMODEL_CLONES
void dot_block(int K, int n, int stride, int begin, int end, const int* __restrict idx,
               const float* __restrict c, const float* __restrict bones, float* __restrict ox,
               float* __restrict oy, float* __restrict oz) {
  for (int v = begin; v < end; ++v) {
    float acc[12] = {0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f};
    const int* __restrict iv = idx + static_cast<size_t>(v) * K;
    const float* __restrict cv = c + static_cast<size_t>(v) * K * 12;
    for (int k = 0; k < K; ++k) {
      const float* __restrict M = bones + 12 * iv[k];
      for (int e = 0; e < 12; ++e) acc[e] += cv[12 * k + e] * M[e];
    }
    ox[v] = acc[0] + acc[1] + acc[2] + acc[3];
    oy[v] = acc[4] + acc[5] + acc[6] + acc[7];
    oz[v] = acc[8] + acc[9] + acc[10] + acc[11];
  }
}

// Normals: out_j = Σ_k Σ_{i<3} c[k][row(j,i)] · bone[12 b + 4j + i], then normalised.
BODYMODEL_CLONES
void normal_block(int K, int n, int stride, int begin, int end, const int* __restrict idx,
                  const float* __restrict c, const float* __restrict nrest, const float* __restrict bones,
                  float* __restrict ox, float* __restrict oy, float* __restrict oz) {
  // stride 1 (LBS weights or AS p_w, times the rest normal), 9 (MWE W ⊙ n).
  float acc[3][kBlock];
  const int len = end - begin;
  for (int j = 0; j < 3; ++j)
    for (int v = 0; v < len; ++v) acc[j][v] = 0.f;
  for (int k = 0; k < K; ++k) {
    const int* __restrict ik = idx + static_cast<size_t>(k) * n + begin;   // slot-major copy
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) {
        const int e = 4 * j + i;
        if (stride == 9) {
          const float* __restrict ck = c + (static_cast<size_t>(k) * 9 + 3 * j + i) * n + begin;
          for (int v = 0; v < len; ++v) acc[j][v] += ck[v] * bones[12 * ik[v] + e];
        } else {
          const float* __restrict ck = c + static_cast<size_t>(k) * n + begin;
          const float* __restrict ni = nrest + static_cast<size_t>(i) * n + begin;
          for (int v = 0; v < len; ++v) acc[j][v] += ck[v] * ni[v] * bones[12 * ik[v] + e];
        }
      }
  }
  for (int v = 0; v < len; ++v) {
    const float l = std::sqrt(acc[0][v] * acc[0][v] + acc[1][v] * acc[1][v] + acc[2][v] * acc[2][v]);
    const float inv = l > 0 ? 1.f / l : 0.f;
    ox[begin + v] = acc[0][v] * inv;
    oy[begin + v] = acc[1][v] * inv;
    oz[begin + v] = acc[2][v] * inv;
  }
}

template <typename F>
void run_blocks(int n, int threads, F&& f) {
  auto body = [&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, (n + kBlock - 1) / kBlock, 8), [&](const auto& r) {
      for (int b = r.begin(); b < r.end(); ++b) f(b * kBlock, std::min(n, (b + 1) * kBlock));
    });
  };
  if (threads > 0) {
    tbb::task_arena arena(threads);
    arena.execute(body);
  } else {
    body();
  }
}

}  // namespace

RuntimeSkinner::RuntimeSkinner(const SkinningRig& rig, const Eigen::MatrixX3d& normals) {
  rig.validate("runtime skinner");
  if (rig.max_influences() > kMaxInfluences)
    throw InputError("runtime skinner: the rig has " + std::to_string(rig.max_influences()) +
                     " influence slots, at most " + std::to_string(kMaxInfluences) + " are supported");
  if (normals.size() && normals.rows() != rig.rest.rows())
    throw InputError("runtime skinner: " + std::to_string(normals.rows()) + " rest normals for " +
                     std::to_string(rig.rest.rows()) + " vertices");
  method_ = rig.method;
  n_ = rig.vertex_count();
  K_ = rig.max_influences();
  B_ = rig.bone_count;
  has_normals_ = normals.size() > 0;
  const size_t n = static_cast<size_t>(n_);
  idx_.assign(static_cast<size_t>(K_) * n, B_);      // vertex-major (positions)
  nidx_.assign(static_cast<size_t>(K_) * n, B_);     // slot-major (normals)
  for (int k = 0; k < K_; ++k)
    for (int i = 0; i < n_; ++i) {
      const int b = rig.influences(i, k) < 0 ? B_ : rig.influences(i, k);
      idx_[static_cast<size_t>(i) * K_ + k] = b;
      nidx_[k * n + i] = b;
    }
  const int c = coefficients_per_influence(method_);
  if (method_ == SkinningMethod::lbs) {
    coef_.assign(static_cast<size_t>(K_) * n, 0.f);    // vertex-major weights
    lcoef_.assign(static_cast<size_t>(K_) * n, 0.f);   // slot-major copy (normals)
    rest_.resize(3 * n);
    for (int i = 0; i < n_; ++i) {
      for (int k = 0; k < K_; ++k) {
        coef_[static_cast<size_t>(i) * K_ + k] = static_cast<float>(rig.coefficients(i, k));
        lcoef_[k * n + i] = static_cast<float>(rig.coefficients(i, k));
      }
      for (int d = 0; d < 3; ++d) rest_[3 * static_cast<size_t>(i) + d] = static_cast<float>(rig.rest(i, d));
    }
  } else if (method_ == SkinningMethod::animation_space) {
    coef_.assign(static_cast<size_t>(K_) * 12 * n, 0.f);
    for (int i = 0; i < n_; ++i)
      for (int k = 0; k < K_; ++k)
        for (int r = 0; r < 12; ++r)
          coef_[(static_cast<size_t>(i) * K_ + k) * 12 + r] = static_cast<float>(rig.coefficients(i, k * c + r % 4));
  } else {
    coef_.assign(static_cast<size_t>(K_) * 12 * n, 0.f);
    for (int i = 0; i < n_; ++i) {
      const double v[4] = {rig.rest(i, 0), rig.rest(i, 1), rig.rest(i, 2), 1.0};
      for (int k = 0; k < K_; ++k)
        for (int r = 0; r < 12; ++r)
          coef_[(static_cast<size_t>(i) * K_ + k) * 12 + r] =
              static_cast<float>(rig.coefficients(i, k * 12 + r) * v[r % 4]);
    }
  }
  if (has_normals_) {
    if (method_ == SkinningMethod::mwe) {
      ncoef_.assign(static_cast<size_t>(K_) * 9 * n, 0.f);
      for (int i = 0; i < n_; ++i)
        for (int k = 0; k < K_; ++k)
          for (int j = 0; j < 3; ++j)
            for (int q = 0; q < 3; ++q)
              ncoef_[(k * 9 + 3 * j + q) * n + i] =
                  static_cast<float>(rig.coefficients(i, k * 12 + 4 * j + q) * normals(i, q));
    } else {
      nrest_.resize(3 * n);
      for (int i = 0; i < n_; ++i)
        for (int d = 0; d < 3; ++d) nrest_[d * n + i] = static_cast<float>(normals(i, d));
      if (method_ == SkinningMethod::animation_space) {   // p_k,w: the weight part of p_k
        ncoef_.assign(static_cast<size_t>(K_) * n, 0.f);
        for (int i = 0; i < n_; ++i)
          for (int k = 0; k < K_; ++k) ncoef_[k * n + i] = static_cast<float>(rig.coefficients(i, k * 4 + 3));
      }
    }
  }
}

void RuntimeSkinner::pack_bones(const BoneTransforms& M, std::vector<float>* out) const {
  if (static_cast<int>(M.size()) != B_)
    throw InputError("runtime skinner: " + std::to_string(M.size()) + " bone transforms for a rig of " +
                     std::to_string(B_) + " bones");
  out->assign(static_cast<size_t>(B_ + 1) * 12, 0.f);   // bone B = zero matrix for unused slots
  for (int b = 0; b < B_; ++b)
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) (*out)[12 * b + 4 * r + c] = static_cast<float>(M[static_cast<size_t>(b)].matrix()(r, c));
}

void RuntimeSkinner::pose(const BoneTransforms& M, float* x, float* y, float* z, int threads) const {
  std::vector<float> bones;
  pack_bones(M, &bones);
  const float* bp = bones.data();
  if (method_ == SkinningMethod::lbs) {
    run_blocks(n_, threads, [&](int b, int e) { lbs_block(K_, n_, b, e, idx_.data(), coef_.data(), rest_.data(), bp, x, y, z); });
  } else {
    const int stride = 12;
    run_blocks(n_, threads, [&](int b, int e) { dot_block(K_, n_, stride, b, e, idx_.data(), coef_.data(), bp, x, y, z); });
  }
}

void RuntimeSkinner::pose_normals(const BoneTransforms& M, float* nx, float* ny, float* nz, int threads) const {
  if (!has_normals_) throw InputError("runtime skinner: built without rest normals");
  std::vector<float> bones;
  pack_bones(M, &bones);
  const float* bp = bones.data();
  const int stride = method_ == SkinningMethod::mwe ? 9 : 1;
  const float* c = method_ == SkinningMethod::lbs ? lcoef_.data() : ncoef_.data();
  run_blocks(n_, threads, [&](int b, int e) {
    normal_block(K_, n_, stride, b, e, nidx_.data(), c, nrest_.data(), bp, nx, ny, nz);
  });
}

Eigen::MatrixX3f RuntimeSkinner::pose(const BoneTransforms& M, int threads) const {
  std::vector<float> x(static_cast<size_t>(n_)), y(static_cast<size_t>(n_)), z(static_cast<size_t>(n_));
  pose(M, x.data(), y.data(), z.data(), threads);
  Eigen::MatrixX3f out(n_, 3);
  for (int i = 0; i < n_; ++i) out.row(i) << x[static_cast<size_t>(i)], y[static_cast<size_t>(i)], z[static_cast<size_t>(i)];
  return out;
}

}  // namespace bodymodel
