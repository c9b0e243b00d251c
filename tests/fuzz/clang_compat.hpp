#pragma once
// Force-included (-include) into every file of the fuzz build (clang): GCC's vector shuffles,
// used by src/runtime/simd.hpp, which clang does not have (clang has
// __builtin_shufflevector with constant indices instead). Same semantics as GCC's, for
// vectors of N elements (N a power of two, as GCC requires):
//   one operand:  element i of the result is a[mask[i] mod N];
//   two operands: element i of the result is (a concatenated with b)[mask[i] mod 2N],
//                 i.e. a[m] for m < N and b[m - N] otherwise, with m = mask[i] mod 2N.
#if defined(__clang__) && defined(__cplusplus)
template <typename V, typename M>
inline V __builtin_shuffle(V a, M mask) {
  constexpr int n = static_cast<int>(sizeof(V) / sizeof(a[0]));
  static_assert(n > 0 && (n & (n - 1)) == 0, "GCC's shuffle needs a power-of-two vector length");
  V r = a;
  for (int i = 0; i < n; ++i) r[i] = a[static_cast<int>(mask[i]) & (n - 1)];
  return r;
}

template <typename V, typename M>
inline V __builtin_shuffle(V a, V b, M mask) {
  constexpr int n = static_cast<int>(sizeof(V) / sizeof(a[0]));
  static_assert(n > 0 && (n & (n - 1)) == 0, "GCC's shuffle needs a power-of-two vector length");
  V r = a;
  for (int i = 0; i < n; ++i) {
    const int m = static_cast<int>(mask[i]) & (2 * n - 1);
    r[i] = m < n ? a[m] : b[m - n];
  }
  return r;
}
#endif
