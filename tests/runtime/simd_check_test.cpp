// Which branch of src/runtime/simd.hpp this build compiled, and that its lane-wise
// helpers agree with scalar arithmetic. tools/arm64_check.sh runs this binary under
// qemu-aarch64 and also greps the binary itself (strings, not its output) for the backend
// marker string below.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "runtime/simd.hpp"

namespace omnipose::runtime {
namespace {

// Kept whole in the binary's read-only data (gnu::used: emitted even if the compiler could
// drop or split it) for tools/arm64_check.sh: "omnipose-simd-backend=neon" on arm64.
[[gnu::used]] const char kMarker[] = "omnipose-simd-backend=" OMNIPOSE_SIMD_BACKEND;

TEST(Simd, TheArchitecturesVectorBranchIsCompiled) {
  RecordProperty("simd_backend", kMarker);
#if defined(__aarch64__)
  EXPECT_STREQ(simd::kBackend, "neon");
#elif defined(__x86_64__)
  EXPECT_STREQ(simd::kBackend, "sse2");
#else
  GTEST_SKIP() << "no vector branch for this architecture: " << simd::kBackend;
#endif
}

// a * b + c, compiled once per target of OMNIPOSE_SIMD_CLONES, as the hot loops are.
OMNIPOSE_SIMD_CLONES
float multiplyAdd(float a, float b, float c) { return a * b + c; }

TEST(Simd, HotLoopsRunTheMultiplyAddCopyOnCpusThatHaveIt) {
  // (1 + 2^-12)^2 = 1 + 2^-11 + 2^-24 does not fit a float (ties to 1 + 2^-11): minus
  // 1 + 2^-11 it is 2^-24 when the multiply-add is fused, 0 when the product is rounded first.
  volatile float a = 1.0f + 0x1p-12f;
  const float got = multiplyAdd(a, a, -(1.0f + 0x1p-11f));
#if OMNIPOSE_HAS_SIMD_CLONES  // x86-64: __builtin_cpu_supports knows "x86-64-v3"
  __builtin_cpu_init();
  const bool v3 = __builtin_cpu_supports("x86-64-v3");
  RecordProperty("x86_64_v3_copy", v3 ? "yes" : "no (baseline copy)");
  EXPECT_EQ(got, v3 ? 0x1p-24f : 0.0f) << "x86-64-v3 copy: " << (v3 ? "yes" : "no (baseline copy)");
#else
  (void)got;
  GTEST_SKIP() << "OMNIPOSE_SIMD_CLONES is empty here: one copy";
#endif
}

TEST(Simd, LaneWiseHelpersMatchScalarArithmetic) {
  const simd::F4 x{0.25f, 2.0f, 9.0f, 1e4f};
  const simd::F4 r = simd::sqrt(x);
  const simd::F4 q = simd::rsqrt(x);
  for (int l = 0; l < 4; ++l) {
    EXPECT_FLOAT_EQ(r[l], std::sqrt(x[l]));
    EXPECT_NEAR(q[l] * std::sqrt(x[l]), 1.0f, 1e-6f) << "rsqrt lane " << l;
  }
  // (1 + 2i) conj(3 - i) = (1 + 2i)(3 + i) = 1 + 7i; (0.5 - i) conj(2 + 2i) = -1 - 3i.
  const simd::F4 a{1.0f, 2.0f, 0.5f, -1.0f}, b{3.0f, -1.0f, 2.0f, 2.0f};
  const simd::F4 m = simd::mulConj(a, b);
  EXPECT_FLOAT_EQ(m[0], 1.0f);
  EXPECT_FLOAT_EQ(m[1], 7.0f);
  EXPECT_FLOAT_EQ(m[2], -1.0f);
  EXPECT_FLOAT_EQ(m[3], -3.0f);
  const simd::F4 n = simd::pairNorm(a);
  EXPECT_FLOAT_EQ(n[0], 5.0f);
  EXPECT_FLOAT_EQ(n[1], 5.0f);
  EXPECT_FLOAT_EQ(n[2], 1.25f);
  const simd::F4 n4 = simd::norms(a, b);  // |1+2i|^2, |0.5-i|^2, |3-i|^2, |2+2i|^2
  EXPECT_FLOAT_EQ(n4[0], 5.0f);
  EXPECT_FLOAT_EQ(n4[1], 1.25f);
  EXPECT_FLOAT_EQ(n4[2], 10.0f);
  EXPECT_FLOAT_EQ(n4[3], 8.0f);
  const simd::F4 lo = simd::lowPairs(x), hi = simd::highPairs(x);
  for (int l = 0; l < 4; ++l) {
    EXPECT_EQ(lo[l], x[l / 2]) << "lowPairs lane " << l;
    EXPECT_EQ(hi[l], x[2 + l / 2]) << "highPairs lane " << l;
  }
  EXPECT_FLOAT_EQ(simd::sum(x), 0.25f + 2.0f + 9.0f + 1e4f);
  EXPECT_FLOAT_EQ(simd::maxLane(x), 1e4f);
  // NaN lanes are ignored wherever they are (std::fmax's rule); all NaN gives NaN.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(simd::maxLane(simd::F4{nan, -1.0f, -3.0f, -2.0f}), -1.0f);
  EXPECT_EQ(simd::maxLane(simd::F4{-4.0f, nan, nan, -5.0f}), -4.0f);
  EXPECT_EQ(simd::maxLane(simd::F4{-4.0f, -6.0f, -5.0f, nan}), -4.0f);
  EXPECT_TRUE(std::isnan(simd::maxLane(simd::F4{nan, nan, nan, nan})));
  EXPECT_EQ(simd::maxLane(simd::F4{-7.0f, -7.0f, -7.0f, -7.0f}), -7.0f);
}

TEST(Simd, TransposeSwapsRowsAndColumns) {
  simd::F4 rows[4];
  for (int i = 0; i < 4; ++i)
    rows[i] = simd::F4{10.0f * i, 10.0f * i + 1, 10.0f * i + 2, 10.0f * i + 3};
  simd::transpose(rows[0], rows[1], rows[2], rows[3]);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) EXPECT_EQ(rows[i][j], 10.0f * j + i) << "element " << i << ", " << j;
}

TEST(Simd, FloorToIntRoundsTowardsMinusInfinity) {
  const float values[] = {-2.5f, -2.0f, -0.25f, -1e-7f, 0.0f, 0.75f, 3.0f, 1e6f + 0.5f, -1e6f - 0.5f,
                          107.999f};
  for (float v : values) {
    const simd::I4 f = simd::floorToInt(simd::F4{v, -v, v + 1.0f, v - 1.0f});
    EXPECT_EQ(f[0], static_cast<int>(std::floor(v))) << v;
    EXPECT_EQ(f[1], static_cast<int>(std::floor(-v))) << -v;
    EXPECT_EQ(f[2], static_cast<int>(std::floor(v + 1.0f))) << v + 1.0f;
    EXPECT_EQ(f[3], static_cast<int>(std::floor(v - 1.0f))) << v - 1.0f;
  }
}

}  // namespace
}  // namespace omnipose::runtime
