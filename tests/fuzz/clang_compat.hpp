#pragma once
// Force-included (-include) into every file of the fuzz build (clang): GCC's one-operand
// vector shuffle, used by src/registration/simd.hpp, which clang does not have (clang has
// __builtin_shufflevector with constant indices instead). Same semantics as GCC's: element
// i of the result is a[mask[i] mod N].
#if defined(__clang__) && defined(__cplusplus)
template <typename V, typename M>
inline V __builtin_shuffle(V a, M mask) {
  constexpr int n = static_cast<int>(sizeof(V) / sizeof(a[0]));
  V r = a;
  for (int i = 0; i < n; ++i) r[i] = a[static_cast<int>(mask[i]) & (n - 1)];
  return r;
}
#endif
