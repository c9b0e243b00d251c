#pragma once
/// \file simd.hpp
/// Four-lane float vectors (GCC/Clang vector extensions: SSE on x86-64, NEON on AArch64,
/// plain scalar code elsewhere) for the hot loops of the registration. The project builds
/// with -O2, where GCC 12 auto-vectorises almost nothing; these keep the per-window work
/// small without target-specific flags. Results are IEEE-exact per lane (no fast-math),
/// except that GCC fuses a * b + c into one multiply-add (one rounding; C++'s default
/// -ffp-contract=fast) where the target has one: on AArch64 (NEON fmla) and in the x86-64-v3
/// copies of OMNIPOSE_SIMD_CLONES, not in x86-64's SSE2 baseline. So results differ in the
/// last bits between those, each deterministic for any thread count.

#include <cmath>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#define OMNIPOSE_SIMD_BACKEND "sse2"
#elif defined(__ARM_NEON) && defined(__aarch64__)
#include <arm_neon.h>
#define OMNIPOSE_SIMD_BACKEND "neon"
#else
#define OMNIPOSE_SIMD_BACKEND "scalar"
#endif
#if defined(__aarch64__) && !defined(__ARM_NEON)
#error "AArch64 without __ARM_NEON: simd.hpp would fall back to its scalar branch"
#endif

/// OMNIPOSE_SIMD_CLONES, on the functions that hold the hot loops: on x86-64 with GCC, two
/// copies of the function, one for the x86-64 baseline (SSE2) and one for x86-64-v3 (AVX2,
/// FMA: VEX encoding, and a * b + c fused into one multiply-add), of which the dynamic loader
/// picks the second on CPUs that have it (GCC's target_clones, an ifunc), as FFTW and OpenCV
/// pick their kernels; the binary still runs on any x86-64. One process always runs one copy,
/// so results stay bit-identical for any thread count; a CPU without AVX2 and FMA computes
/// the last bits differently, as arm64 does. Elsewhere (AArch64 has its multiply-add in the
/// baseline) and under OMNIPOSE_NO_SIMD_CLONES it is empty; OMNIPOSE_HAS_SIMD_CLONES says which
/// (1: two copies, 0: one).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && \
    !defined(OMNIPOSE_NO_SIMD_CLONES)
#define OMNIPOSE_SIMD_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#define OMNIPOSE_HAS_SIMD_CLONES 1
#else
#define OMNIPOSE_SIMD_CLONES
#define OMNIPOSE_HAS_SIMD_CLONES 0
#endif

namespace omnipose::runtime::simd {

/// Which branch of this header was compiled: "sse2", "neon" or "scalar"
/// (tools/arm64_check.sh checks for "neon" in the arm64 build).
inline constexpr const char* kBackend = OMNIPOSE_SIMD_BACKEND;

using F4 = float __attribute__((vector_size(16)));
using I4 = int __attribute__((vector_size(16)));

/// Unaligned load / store of four floats.
inline F4 load(const float* p) {
  F4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store(float* p, F4 v) { std::memcpy(p, &v, sizeof v); }
inline F4 broadcast(float x) { return F4{x, x, x, x}; }

/// Lane-wise square root (lanes >= 0).
inline F4 sqrt(F4 x) {
#if defined(__SSE2__)
  return reinterpret_cast<F4>(_mm_sqrt_ps(reinterpret_cast<__m128>(x)));
#elif defined(__ARM_NEON) && defined(__aarch64__)
  return reinterpret_cast<F4>(vsqrtq_f32(reinterpret_cast<float32x4_t>(x)));
#else
  return F4{std::sqrt(x[0]), std::sqrt(x[1]), std::sqrt(x[2]), std::sqrt(x[3])};
#endif
}

/// Lane-wise 1 / sqrt(x) for x > 0, to ~22 bits: the hardware estimate refined by one
/// Newton step y <- y (3 - x y^2) / 2 (exact division where there is no estimate).
inline F4 rsqrt(F4 x) {
#if defined(__SSE2__)
  const F4 y = reinterpret_cast<F4>(_mm_rsqrt_ps(reinterpret_cast<__m128>(x)));
  return y * (F4{1.5f, 1.5f, 1.5f, 1.5f} - F4{0.5f, 0.5f, 0.5f, 0.5f} * x * y * y);
#elif defined(__ARM_NEON) && defined(__aarch64__)
  const float32x4_t v = reinterpret_cast<float32x4_t>(x);
  float32x4_t y = vrsqrteq_f32(v);
  y = vmulq_f32(y, vrsqrtsq_f32(vmulq_f32(v, y), y));
  y = vmulq_f32(y, vrsqrtsq_f32(vmulq_f32(v, y), y));
  return reinterpret_cast<F4>(y);
#else
  return F4{1.0f, 1.0f, 1.0f, 1.0f} / sqrt(x);
#endif
}

/// Lane-wise floor(x) as integers, for |x| < 2^31 (truncation, minus one where it rounded
/// a negative non-integer up; no libm call per lane).
inline I4 floorToInt(F4 x) {
  const I4 t = __builtin_convertvector(x, I4);
  return t + (__builtin_convertvector(t, F4) > x);  // a true comparison lane is -1
}

inline F4 max(F4 a, F4 b) { return a > b ? a : b; }
inline F4 min(F4 a, F4 b) { return a < b ? a : b; }

/// Sum of the four lanes.
inline float sum(F4 v) { return (v[0] + v[1]) + (v[2] + v[3]); }
/// Largest lane; NaN lanes are ignored, as std::fmax ignores them (all NaN: NaN). Written
/// out because std::fmax is a libm call, not an instruction, without -ffast-math.
inline float maxLane(F4 v) {
  const auto fmax = [](float a, float b) { return (b > a || a != a) ? b : a; };
  return fmax(fmax(v[0], v[1]), fmax(v[2], v[3]));
}

/// Transposes the 4 x 4 matrix whose rows are a, b, c, d (afterwards a = column 0, ...).
inline void transpose(F4& a, F4& b, F4& c, F4& d) {
  const F4 t0 = __builtin_shuffle(a, b, I4{0, 4, 1, 5});  // a0 b0 a1 b1
  const F4 t1 = __builtin_shuffle(a, b, I4{2, 6, 3, 7});  // a2 b2 a3 b3
  const F4 t2 = __builtin_shuffle(c, d, I4{0, 4, 1, 5});  // c0 d0 c1 d1
  const F4 t3 = __builtin_shuffle(c, d, I4{2, 6, 3, 7});  // c2 d2 c3 d3
  a = __builtin_shuffle(t0, t2, I4{0, 1, 4, 5});
  b = __builtin_shuffle(t0, t2, I4{2, 3, 6, 7});
  c = __builtin_shuffle(t1, t3, I4{0, 1, 4, 5});
  d = __builtin_shuffle(t1, t3, I4{2, 3, 6, 7});
}

/// For interleaved complex pairs (re0, im0, re1, im1): (|z0|^2, |z0|^2, |z1|^2, |z1|^2).
inline F4 pairNorm(F4 z) {
  const F4 sq = z * z;
  return sq + __builtin_shuffle(sq, I4{1, 0, 3, 2});
}

/// For four interleaved complex numbers, z01 = (re0, im0, re1, im1) and z23 = (re2, im2, re3,
/// im3): (|z0|^2, |z1|^2, |z2|^2, |z3|^2), each re^2 + im^2 as pairNorm() computes it.
inline F4 norms(F4 z01, F4 z23) {
  const F4 a = z01 * z01, b = z23 * z23;
  return __builtin_shuffle(a, b, I4{0, 2, 4, 6}) + __builtin_shuffle(a, b, I4{1, 3, 5, 7});
}

/// Lane L of v in all four lanes (one shuffle).
template <int L>
inline F4 splat(F4 v) {
  static_assert(L >= 0 && L < 4);
  return __builtin_shuffle(v, I4{L, L, L, L});
}

/// (x0, x0, x1, x1) and (x2, x2, x3, x3): per-number factors back onto interleaved complex lanes.
inline F4 lowPairs(F4 x) { return __builtin_shuffle(x, I4{0, 0, 1, 1}); }
inline F4 highPairs(F4 x) { return __builtin_shuffle(x, I4{2, 2, 3, 3}); }

/// For interleaved complex pairs: a * conj(b), lane-wise per complex number.
inline F4 mulConj(F4 a, F4 b) {
  // (ar + i ai)(br - i bi) = (ar br + ai bi) + i (ai br - ar bi)
  const F4 a_swapped = __builtin_shuffle(a, I4{1, 0, 3, 2});  // (ai, ar, ...)
  const F4 b_real = __builtin_shuffle(b, I4{0, 0, 2, 2});     // (br, br, ...)
  const F4 b_imag = __builtin_shuffle(b, I4{1, 1, 3, 3});     // (bi, bi, ...)
  const F4 sign = F4{1.0f, -1.0f, 1.0f, -1.0f};
  return a * b_real + a_swapped * b_imag * sign;
}

}  // namespace omnipose::runtime::simd
