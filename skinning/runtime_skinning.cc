#include "skinning/runtime_skinning.h"

#include <cmath>
#include <map>
#include <memory>
#include <mutex>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "core/error.h"

namespace bodymodel {
namespace {

constexpr int kBlock = 256;

// GCC only: clang rejects target_clones on the function templates below, so a clang build
// compiles the kernels once, for the target it is given (e.g. -march=native for its speed).
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define BODYMODEL_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=haswell", "default")))
#else
#define BODYMODEL_CLONES
#endif

// The 256-bit helpers below are always inlined into the target clones; GCC's note that passing such
// vectors by value in a non-AVX function changes the ABI does not apply.
#pragma GCC diagnostic ignored "-Wpsabi"

// GCC/Clang vector extensions: portable SIMD that each target_clones variant compiles natively
// (AVX2+FMA, AVX-512 or SSE2), loaded and stored with unaligned moves.
typedef float v8sf __attribute__((vector_size(32)));
typedef float v4sf __attribute__((vector_size(16)));

__attribute__((always_inline)) inline v8sf load8(const float* p) {
  v8sf v;
  __builtin_memcpy(&v, p, sizeof v);
  return v;
}
__attribute__((always_inline)) inline v4sf load4(const float* p) {
  v4sf v;
  __builtin_memcpy(&v, p, sizeof v);
  return v;
}
__attribute__((always_inline)) inline v4sf lo(v8sf v) { return v4sf{v[0], v[1], v[2], v[3]}; }
__attribute__((always_inline)) inline v4sf hi(v8sf v) { return v4sf{v[4], v[5], v[6], v[7]}; }

// LBS, K slots: per vertex blend the slots' bone matrices, stored column-major and padded
// ([c0 0 c1 0 | c2 0 t 0], 16 floats = two 8-wide registers), with the vertex's weights (2 FMAs
// per slot, no gathers), then apply the blend to the rest position: 1 multiply + 1 FMA.
template <int K>
BODYMODEL_CLONES void lbs_block(int begin, int end, const uint16_t* __restrict idx, const float* __restrict w,
                                const float* __restrict rest, const float* __restrict bones, float* __restrict ox,
                                float* __restrict oy, float* __restrict oz) {
  for (int v = begin; v < end; ++v) {
    const uint16_t* iv = idx + static_cast<size_t>(v) * K;
    const float* wv = w + static_cast<size_t>(v) * K;
    v8sf m01 = {}, m23 = {};
    for (int k = 0; k < K; ++k) {
      const float* B = bones + 16 * static_cast<size_t>(iv[k]);
      const float wk = wv[k];
      m01 += wk * load8(B);
      m23 += wk * load8(B + 8);
    }
    const v4sf r = load4(rest + 3 * static_cast<size_t>(v));   // x y z (next x): rest has 1 float of padding
    const v4sf one = {1.f, 1.f, 1.f, 1.f};
    const v8sf xy = __builtin_shufflevector(r, r, 0, 0, 0, 0, 1, 1, 1, 1);
    const v8sf z1 = __builtin_shufflevector(r, one, 2, 2, 2, 2, 4, 4, 4, 4);
    const v8sf s = m01 * xy + m23 * z1;
    const v4sf o = lo(s) + hi(s);
    ox[v] = o[0];
    oy[v] = o[1];
    oz[v] = o[2];
  }
}

// Animation Space, K slots: v' = Σ_k M_k p_k with the same column-major bones; p_k (4 floats per
// slot, vertex-major) is spread to [x x x x y y y y], [z z z z w w w w] by two shuffles.
template <int K>
BODYMODEL_CLONES void as_block(int begin, int end, const uint16_t* __restrict idx, const float* __restrict p,
                               const float* __restrict bones, float* __restrict ox, float* __restrict oy,
                               float* __restrict oz) {
  for (int v = begin; v < end; ++v) {
    const uint16_t* iv = idx + static_cast<size_t>(v) * K;
    const float* pv = p + static_cast<size_t>(v) * K * 4;
    v8sf acc = {};
    for (int k = 0; k < K; ++k) {
      const float* B = bones + 16 * static_cast<size_t>(iv[k]);
      const v4sf pk = load4(pv + 4 * k);
      acc += load8(B) * __builtin_shufflevector(pk, pk, 0, 0, 0, 0, 1, 1, 1, 1) +
             load8(B + 8) * __builtin_shufflevector(pk, pk, 2, 2, 2, 2, 3, 3, 3, 3);
    }
    const v4sf r = lo(acc) + hi(acc);
    ox[v] = r[0];
    oy[v] = r[1];
    oz[v] = r[2];
  }
}

// MWE, K slots: out_j = Σ_k Σ_i U_k[j][i] · (M_k)_ji with U = W ⊙ ṽ (12 floats per slot,
// vertex-major) and the bones row-major ([R0 t0 R1 t1 R2 t2], 12 floats): rows 0-1 are one
// 8-wide multiply-add, row 2 a 4-wide one; three horizontal sums at the end.
template <int K>
BODYMODEL_CLONES void mwe_block(int begin, int end, const uint16_t* __restrict idx, const float* __restrict c,
                                const float* __restrict bones, float* __restrict ox, float* __restrict oy,
                                float* __restrict oz) {
  for (int v = begin; v < end; ++v) {
    const uint16_t* iv = idx + static_cast<size_t>(v) * K;
    const float* cv = c + static_cast<size_t>(v) * K * 12;
    v8sf a01 = {};
    v4sf a2 = {};
    for (int k = 0; k < K; ++k) {
      const float* B = bones + 12 * static_cast<size_t>(iv[k]);
      a01 += load8(cv + 12 * k) * load8(B);
      a2 += load4(cv + 12 * k + 8) * load4(B + 8);
    }
    // [r0 r0 r0 r0 r1 r1 r1 r1] + [r2 ...]: pairwise sums.
    const v4sf a = lo(a01), b = hi(a01);
    ox[v] = (a[0] + a[1]) + (a[2] + a[3]);
    oy[v] = (b[0] + b[1]) + (b[2] + b[3]);
    oz[v] = (a2[0] + a2[1]) + (a2[2] + a2[3]);
  }
}

// Dispatch on the slot count (compile-time K: fully unrolled slot loops).
template <template <int> class Kernel, typename... Args>
void dispatch_k(int K, Args... args) {
  switch (K) {
    case 1: Kernel<1>::run(args...); break;
    case 2: Kernel<2>::run(args...); break;
    case 3: Kernel<3>::run(args...); break;
    case 4: Kernel<4>::run(args...); break;
    case 5: Kernel<5>::run(args...); break;
    case 6: Kernel<6>::run(args...); break;
    case 7: Kernel<7>::run(args...); break;
    default: Kernel<8>::run(args...); break;
  }
}
template <int K>
struct LbsKernel {
  template <typename... A>
  static void run(A... a) { lbs_block<K>(a...); }
};
template <int K>
struct AsKernel {
  template <typename... A>
  static void run(A... a) { as_block<K>(a...); }
};
template <int K>
struct MweKernel {
  template <typename... A>
  static void run(A... a) { mwe_block<K>(a...); }
};

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

// One arena per thread limit, created on first use and kept (creating an arena per call costs
// more than posing a small character).
tbb::task_arena& arena_for(int threads) {
  static std::mutex mutex;
  static std::map<int, std::unique_ptr<tbb::task_arena>> arenas;
  std::lock_guard<std::mutex> lock(mutex);
  auto& a = arenas[threads];
  if (!a) a = std::make_unique<tbb::task_arena>(threads);
  return *a;
}

template <typename F>
void run_blocks(int n, int threads, F&& f) {
  if (threads == 1) {   // no scheduler at all
    f(0, n);
    return;
  }
  auto body = [&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, (n + kBlock - 1) / kBlock, 8), [&](const auto& r) {
      f(r.begin() * kBlock, std::min(n, r.end() * kBlock));
    });
  };
  if (threads > 0) {
    arena_for(threads).execute(body);
  } else {
    body();
  }
}

}  // namespace

RuntimeSkinner::RuntimeSkinner(const SkinningRig& rig, const Eigen::MatrixX3d& normals) {
  rig.validate("runtime skinner");
  if (rig.method == SkinningMethod::dqs)
    throw InputError("runtime skinner: dqs rigs are not supported (linear kernels only); pose them with "
                     "evaluate_rig (the reference dual-quaternion blend)");
  if (rig.max_influences() > kMaxInfluences)
    throw InputError("runtime skinner: the rig has " + std::to_string(rig.max_influences()) +
                     " influence slots, at most " + std::to_string(kMaxInfluences) + " are supported");
  if (rig.bone_count >= 65535)
    throw InputError("runtime skinner: the rig has " + std::to_string(rig.bone_count) + " bones, at most 65534 are supported");
  if (normals.size() && normals.rows() != rig.rest.rows())
    throw InputError("runtime skinner: " + std::to_string(normals.rows()) + " rest normals for " +
                     std::to_string(rig.rest.rows()) + " vertices");
  method_ = rig.method;
  n_ = rig.vertex_count();
  K_ = rig.max_influences();
  B_ = rig.bone_count;
  has_normals_ = normals.size() > 0;
  const size_t n = static_cast<size_t>(n_);
  idx_.assign(static_cast<size_t>(K_) * n, static_cast<uint16_t>(B_));   // vertex-major (positions)
  nidx_.assign(static_cast<size_t>(K_) * n, B_);                         // slot-major (normals)
  for (int k = 0; k < K_; ++k)
    for (int i = 0; i < n_; ++i) {
      const int b = rig.influences(i, k) < 0 ? B_ : rig.influences(i, k);
      idx_[static_cast<size_t>(i) * K_ + k] = static_cast<uint16_t>(b);
      nidx_[k * n + i] = b;
    }
  const int c = coefficients_per_influence(method_);
  if (method_ == SkinningMethod::lbs) {
    coef_.assign(static_cast<size_t>(K_) * n, 0.f);    // vertex-major weights
    lcoef_.assign(static_cast<size_t>(K_) * n, 0.f);   // slot-major copy (normals)
    rest_.assign(3 * n + 1, 0.f);   // + 1: the kernel reads 4 floats at each vertex
    for (int i = 0; i < n_; ++i) {
      for (int k = 0; k < K_; ++k) {
        coef_[static_cast<size_t>(i) * K_ + k] = static_cast<float>(rig.coefficients(i, k));
        lcoef_[k * n + i] = static_cast<float>(rig.coefficients(i, k));
      }
      for (int d = 0; d < 3; ++d) rest_[3 * static_cast<size_t>(i) + d] = static_cast<float>(rig.rest(i, d));
    }
  } else if (method_ == SkinningMethod::animation_space) {
    coef_.assign(static_cast<size_t>(K_) * 4 * n, 0.f);
    for (int i = 0; i < n_; ++i)
      for (int k = 0; k < K_; ++k)
        for (int r = 0; r < 4; ++r)
          coef_[(static_cast<size_t>(i) * K_ + k) * 4 + r] = static_cast<float>(rig.coefficients(i, k * c + r));
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

void RuntimeSkinner::pack_bones(const BoneTransforms& M, bool column_major, std::vector<float>* out) const {
  if (static_cast<int>(M.size()) != B_)
    throw InputError("runtime skinner: " + std::to_string(M.size()) + " bone transforms for a rig of " +
                     std::to_string(B_) + " bones");
  const int stride = column_major ? 16 : 12;
  out->assign(static_cast<size_t>(B_ + 1) * stride, 0.f);   // bone B = zero matrix for unused slots
  for (int b = 0; b < B_; ++b) {
    const auto& A = M[static_cast<size_t>(b)].matrix();
    if (!A.allFinite())
      throw InputError("runtime skinner: bone " + std::to_string(b) + "'s transform contains NaN or infinite values");
    float* o = out->data() + static_cast<size_t>(b) * stride;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) {
        if (column_major) o[4 * c + r] = static_cast<float>(A(r, c));
        else o[4 * r + c] = static_cast<float>(A(r, c));
      }
  }
}

void RuntimeSkinner::pose(const BoneTransforms& M, float* x, float* y, float* z, int threads) const {
  std::vector<float> bones;
  pack_bones(M, method_ != SkinningMethod::mwe, &bones);
  const float* bp = bones.data();
  const uint16_t* ip = idx_.data();
  const float* cp = coef_.data();
  if (method_ == SkinningMethod::lbs) {
    const float* rp = rest_.data();
    run_blocks(n_, threads, [&](int b, int e) { dispatch_k<LbsKernel>(K_, b, e, ip, cp, rp, bp, x, y, z); });
  } else if (method_ == SkinningMethod::animation_space) {
    run_blocks(n_, threads, [&](int b, int e) { dispatch_k<AsKernel>(K_, b, e, ip, cp, bp, x, y, z); });
  } else {
    run_blocks(n_, threads, [&](int b, int e) { dispatch_k<MweKernel>(K_, b, e, ip, cp, bp, x, y, z); });
  }
}

void RuntimeSkinner::pose_normals(const BoneTransforms& M, float* nx, float* ny, float* nz, int threads) const {
  if (!has_normals_) throw InputError("runtime skinner: built without rest normals");
  std::vector<float> bones;
  pack_bones(M, false, &bones);
  const float* bp = bones.data();
  const int stride = method_ == SkinningMethod::mwe ? 9 : 1;
  const float* c = method_ == SkinningMethod::lbs ? lcoef_.data() : ncoef_.data();
  run_blocks(n_, threads, [&](int b, int e) {
    for (int s = b; s < e; s += kBlock)   // normal_block works on at most kBlock vertices
      normal_block(K_, n_, stride, s, std::min(e, s + kBlock), nidx_.data(), c, nrest_.data(), bp, nx, ny, nz);
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
